"""The numba-compiled model gives the interpreted model's trajectories."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.errors import SimulationError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import Simulator, simulate

pytestmark = pytest.mark.skipif(not accelerate.available(), reason="numba not installed")


@pytest.mark.parametrize(
    "params",
    [
        Parameters(),
        with_updates(Parameters(), method="euler", substeps=20, spool_time_constant_s=0.0),
        with_updates(Parameters(), method="ros2", piston_dead_volume_m3=1e-6, rod_dead_volume_m3=1e-6),
        config.load(CONFIG / "paper_fig10.yaml"),
    ],
    ids=["physical-rk4", "physical-euler-substeps", "physical-ros2-stiff", "paper-rk4"],
)
def test_compiled_and_interpreted_trajectories_agree(params):
    command = steps([0.0, 0.6, 0.9], [1.0, 0.0, -0.5]) if params.mode == "physical" else (lambda t: 1.0)
    interpreted = simulate(params, 1.2, command, jit=False)
    compiled = simulate(params, 1.2, command, jit=True)
    for name in ("q1", "v", "p1", "p2", "supply_energy"):
        ref = interpreted[name]
        scale = max(np.max(np.abs(ref)), 1e-9)
        assert np.max(np.abs(compiled[name] - ref)) <= 1e-9 * scale, name


def test_compiled_path_reports_leaving_the_geometry():
    sim = Simulator(config.load(CONFIG / "paper_fig8.yaml"), jit=True)
    with pytest.raises(SimulationError, match=r"non-finite.*valid geometry \(1, 1.8\) m"):
        sim.step(1.0, 3000)
    assert 1.7 < sim.y[0] < 1.8  # the last finite state is kept
