"""programs.Forked: a share of a program's work in a forked child (the sweep's plots, half each)."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.errors import BoomHydraulicsError, ConfigError
from boom_hydraulics.files import atomic_path
from boom_hydraulics.model import config
from boom_hydraulics.programs import Forked, Terminated, run_main
from boom_hydraulics.sweeps import plots, plotter, sweep
from boom_hydraulics.sweeps.sampling import parse_axis

GUARD_S = 60


def _raising(exc: BaseException):
    def work() -> None:
        raise exc

    return work


def test_the_childs_work_is_done_when_wait_returns(tmp_path):
    forked = Forked(lambda: (tmp_path / "made").write_text("by the child"))
    forked.wait()
    assert (tmp_path / "made").read_text() == "by the child"
    forked.wait()  # (once waited, again is nothing)


@pytest.mark.parametrize(
    ("raised", "expected", "words"),
    [
        (OSError(errno.ENOSPC, "No space left on device", "/out/plot.png"), OSError, "No space left"),
        (ConfigError("a bad value"), ConfigError, "a bad value"),
        (BoomHydraulicsError("a run failed"), BoomHydraulicsError, "a run failed"),
        (ZeroDivisionError("division by zero"), RuntimeError, "ZeroDivisionError: division by zero"),
        (OSError("encoder error -2 when writing image file"), OSError, "encoder error -2"),
        (MemoryError(), MemoryError, None),
        (KeyboardInterrupt(), KeyboardInterrupt, None),
        (Terminated(), Terminated, None),
    ],
    ids=["disk full", "config", "failure", "bug", "no errno", "memory", "ctrl-c", "sigterm"],
)
def test_what_the_child_raised_is_raised_here_as_run_main_reports_it(raised, expected, words):
    with pytest.raises(expected, match=words) as caught:
        Forked(_raising(raised)).wait()
    assert type(caught.value) is expected
    if isinstance(raised, OSError) and raised.errno is not None:  # the same: run_main names the file, the advice
        assert (caught.value.errno, caught.value.filename) == (errno.ENOSPC, "/out/plot.png")
    if expected is BoomHydraulicsError:
        assert not isinstance(caught.value, ConfigError)  # (exit 1, not 2)


def test_a_child_stopped_from_here_removes_the_file_it_was_writing(tmp_path):
    """As the parent does when it fails or is stopped while the child draws: the child takes
    the SIGTERM as a program under run_main does, and its half-written plot is removed."""
    target = tmp_path / "plot.png"
    writing = tmp_path / "writing"

    def work() -> None:
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"half a plot")
            writing.touch()
            ends = time.monotonic() + GUARD_S  # (a drawing that takes long; not stopped, it ends and renames)
            while time.monotonic() < ends:
                time.sleep(0.01)

    def body() -> int:
        forked = Forked(work)
        deadline = time.monotonic() + GUARD_S
        while not writing.exists() and time.monotonic() < deadline:  # the child is writing
            time.sleep(0.01)
        forked.stop()  # returns once the child has ended
        return 0

    assert run_main("test", body) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["writing"]


def _small_sweep() -> tuple[dict, tuple[str, ...]]:
    axes = [parse_axis("piston_diameter=0.04:0.08:3"), parse_axis("payload=0,150")]
    plan = sweep.plan(sweep.request([("default", config.load(CONFIG / "default.yaml"))], axes, duration_s=4.0))
    return sweep.assemble(plan, [sweep.run_batch(batch) for batch in plan.batches]), plan.columns


def test_a_sweeps_plots_drawn_in_two_processes_are_the_ones_drawn_in_one(tmp_path, monkeypatch):
    table, columns = _small_sweep()
    written = {}
    for forking in (False, True):  # (the test's process has threads of its own: fork as boom-sweep does)
        monkeypatch.setattr(plots, "can_fork", lambda forking=forking: forking)
        folder = tmp_path / str(forking)
        paths = plots.plot_all(table, columns, folder)
        written[forking] = {p.name: p.read_bytes() for p in paths}
        assert sorted(p.name for p in folder.iterdir()) == sorted(written[forking])
    assert len(written[True]) == 5 and written[True] == written[False]
    assert all(png[:8] == b"\x89PNG\r\n\x1a\n" for png in written[True].values())
    assert np.isfinite(np.asarray(table["battery_energy_j"], float)).any()  # (so the battery's plots are among them)


def test_the_plotter_process_draws_the_plots_drawn_here(tmp_path):
    """boom-sweep's plotter, forked before the batches, draws from the table it is handed the
    same files plot_all draws in this process, and says which."""
    table, columns = _small_sweep()
    here = plots.plot_all(table, columns, tmp_path / "here")
    drawer = plotter.Plotter()  # (the test's process has threads of its own: fork as boom-sweep does)
    try:
        drawer.draw(table, columns, tmp_path / "plotter")
        names = drawer.wait()
    except BaseException:
        drawer.stop()
        raise
    assert names == [p.name for p in here]
    assert {n: (tmp_path / "plotter" / n).read_bytes() for n in names} == {p.name: p.read_bytes() for p in here}


def test_a_plotter_stopped_before_its_table_draws_nothing_and_is_not_left_behind(tmp_path, monkeypatch):
    drew = tmp_path / "drew"
    monkeypatch.setattr(plots, "plot_all", lambda *args: drew.touch() or [])  # (the child's, after the fork)
    drawer = plotter.Plotter()
    pid = drawer._forked.pid
    drawer.stop()
    with pytest.raises(ProcessLookupError):  # reaped, not a zombie or an orphan
        os.kill(pid, 0)
    assert not drew.exists()
    drawer.stop()  # (again: nothing)


def test_a_child_killed_by_the_system_is_one_line_not_a_traceback():
    """The system out of memory kills a process with SIGKILL: the program's error line names it."""
    with pytest.raises(BoomHydraulicsError, match="was killed by SIGKILL"):
        Forked(lambda: os.kill(os.getpid(), signal.SIGKILL)).wait()


def test_a_plotter_that_fails_says_why_when_waited_for(tmp_path):
    table, columns = _small_sweep()
    del table["lift_time_s"]  # (a table without a plotted metric: a bug of the caller, not hidden)
    drawer = plotter.Plotter()
    drawer.draw(table, columns, tmp_path)
    with pytest.raises(RuntimeError, match="KeyError: 'lift_time_s'"):
        drawer.wait()


def test_what_the_childs_work_returned_comes_back_from_wait():
    assert Forked(lambda: ["metrics_vs_payload_mass_kg.png", 2]).wait() == ["metrics_vs_payload_mass_kg.png", 2]


_STOPPED_WHILE_WAITING = """
import os, select, signal, sys, time
from pathlib import Path
from boom_hydraulics.files import atomic_path
from boom_hydraulics.programs import Forked, run_main

out = Path(sys.argv[1])

def work():
    os.write(1, f"{os.getpid()}\\n".encode())  # the child's pid, for the test to look for it after
    if sys.argv[2] == "large report":
        raise ValueError("x" * 200_000)  # a report larger than a pipe holds
    with atomic_path(out / "plot.png") as tmp:
        tmp.write_bytes(b"half a plot")
        os.kill(os.getppid(), signal.SIGTERM)  # the parent alone is stopped, while it waits
        ends = time.monotonic() + 60
        while time.monotonic() < ends:
            time.sleep(0.01)

def body():
    forked = Forked(work)
    try:  # (the child's SIGTERM may come at once: from here on, this process stops the child)
        if sys.argv[2] == "large report":
            select.select([forked._read], [], [], 60)  # the child writes its report: it fills the pipe
            forked.stop()  # without reading it
        else:
            forked.wait()
    except BaseException:
        forked.stop()
        raise
    return 0

sys.exit(run_main("tool", body))
"""


@pytest.mark.parametrize("how", ["sigterm", "large report"])
def test_a_child_is_never_left_behind_by_a_parent_stopped_while_waiting_or_stopping_it(tmp_path, how):
    """SIGTERM to the parent alone while it waits (kill PID, docker stop): the child is
    stopped and reaped, and writes nothing after the parent's line. A child whose report
    fills the pipe does not hold up stop()."""
    done = subprocess.run(
        [sys.executable, "-c", _STOPPED_WHILE_WAITING, str(tmp_path), how],
        capture_output=True, text=True, timeout=GUARD_S,
    )  # fmt: skip
    child = int(done.stdout.split()[0])
    assert done.returncode == (143 if how == "sigterm" else 0), done.stderr
    with pytest.raises(ProcessLookupError):  # reaped by the parent, not orphaned
        os.kill(child, 0)
    assert list(tmp_path.iterdir()) == []  # its half-written plot removed


def test_a_fork_the_system_refuses_draws_every_plot_here(tmp_path, monkeypatch):
    def refused() -> int:
        raise OSError(errno.EAGAIN, "Resource temporarily unavailable")

    table, columns = _small_sweep()
    monkeypatch.setattr(plots, "can_fork", lambda: True)
    monkeypatch.setattr(os, "fork", refused)
    paths = plots.plot_all(table, columns, tmp_path)
    assert len(paths) == 5 and sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
