"""The node says when it compiles, before the wait: at its start and at a change of its method.
In process, with the compile itself left out (Simulator.warm) and the cache's answer given
(Simulator.compiles_first): what is tested is that the node asks, and says so, first."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from boom_hydraulics.ros.node import BoomSimNode  # noqa: E402
from boom_hydraulics.solve.simulation import Simulator  # noqa: E402

LINE = "the physical model's {} is not compiled on this machine yet: compiling it for {} takes tens of seconds"


@pytest.fixture
def warmed(monkeypatch, capfd):
    """A cache without the model: every warm-up would compile (the compile itself left out).
    Each warm-up notes its method and what the node had logged by then."""
    said: list[tuple[str, str]] = []
    monkeypatch.setattr(Simulator, "compiles_first", lambda self: True)
    monkeypatch.setattr(Simulator, "warm", lambda self: said.append((self.params.method, capfd.readouterr().err)))
    rclpy.init(args=["--ros-args", "-p", "record:=false", "-p", "real_time_factor:=0.0"])
    yield said
    rclpy.shutdown()


def test_the_node_says_it_compiles_before_its_start_and_a_change_of_method_do(warmed):
    node = BoomSimNode()
    try:
        assert node.set_parameters([Parameter("method", value="euler")])[0].successful
    finally:
        node.destroy()
    (start, before_start), (change, before_change) = warmed
    assert start == "rk4" and LINE.format("rk4", "this start") in before_start, before_start
    assert change == "euler" and LINE.format("euler", "this change") in before_change, before_change
