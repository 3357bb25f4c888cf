"""boom-sweep's failure paths as a user meets them: one line, the documented exit status, and the
folder left as it was (or holding only what the sweep names)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import run_tool

BOOM_SWEEP = shutil.which("boom-sweep")
BOOM_SIM_NODE = shutil.which("boom_sim")
pytestmark = pytest.mark.skipif(BOOM_SWEEP is None, reason="boom-sweep not on PATH (run through tools/with-env)")

#: Two points of a short lift, a batch each: a real sweep folder in a few seconds.
TWO = ["--vary", "payload=0,100", "--duration", "0.5", "--lift-angle-deg", "8", "--no-plots"]


def _sweep(*args: object) -> subprocess.CompletedProcess:
    """boom-sweep's main in this process (conftest.run_tool): the tests that signal it run the real one."""
    return run_tool("boom-sweep", *args)


def _one_error(result: subprocess.CompletedProcess, status: int, words: str) -> None:
    """The run ended with ``status`` and its stderr is one line: boom-sweep: error: ...words..."""
    assert result.returncode == status, result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("boom-sweep: error: "), result.stderr
    assert words in result.stderr, result.stderr
    assert "Traceback" not in result.stderr


def _contents(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """A finished two-batch sweep folder; tests work on copies."""
    out = tmp_path_factory.mktemp("finished") / "sweep"
    result = _sweep(*TWO, "--batch-size", 1, "--out", out)
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture
def copy(finished, tmp_path) -> Path:
    target = tmp_path / "sweep"
    shutil.copytree(finished, target)
    return target


@pytest.mark.parametrize(
    "text",
    ["garbage{", "[1, 2]", "null", '{"format": 1, "request": [1]}', '{"format": 1}', "[" * 100_000 + "]" * 100_000],
)
def test_a_damaged_sweep_description_is_one_line_and_changes_nothing(copy, text):
    (copy / "sweep.json").write_text(text)
    before = _contents(copy)
    result = _sweep(*TWO, "--batch-size", 1, "--out", copy, "--resume")
    _one_error(result, 1, f"{copy / 'sweep.json'} is damaged")
    assert "2 batches stored beside it" in result.stderr
    assert _contents(copy) == before
    again = _sweep(*TWO, "--batch-size", 1, "--out", copy)  # without --resume: the same advice, not "pass --resume"
    _one_error(again, 1, "is damaged")


def test_a_foreign_batch_file_is_named_and_the_advice_leads_somewhere(copy, tmp_path):
    """Another sweep's batch in batches/: --resume names it and says to move it (without --resume the
    tool says --resume, which names the file again, never "rerun without --resume")."""
    stray = copy / "batches" / "00007.npz"
    shutil.copy(copy / "batches" / "00000.npz", stray)
    before = _contents(copy)
    resumed = _sweep(*TWO, "--out", copy, "--resume")
    _one_error(resumed, 2, f"{stray} is not a batch of this sweep")
    assert "move it out of" in resumed.stderr and "without --resume" not in resumed.stderr
    _one_error(_sweep(*TWO, "--out", copy), 2, "pass --resume")
    assert _contents(copy) == before
    stray.rename(tmp_path / "moved.npz")  # as the line says
    finished = _sweep(*TWO, "--out", copy, "--resume")
    assert finished.returncode == 0, finished.stderr
    assert "2 done before, 0 to run" in finished.stderr


def test_a_batch_file_holding_other_points_is_named_and_kept(copy):
    theirs = copy / "batches" / "00001.npz"
    shutil.copy(copy / "batches" / "00000.npz", theirs)
    before = _contents(copy)
    result = _sweep(*TWO, "--out", copy, "--resume")
    _one_error(result, 2, f"{theirs} is not this sweep's batch 1 (it holds points 0, not 1)")
    assert _contents(copy) == before


def test_a_cut_batch_file_is_kept_aside_and_computed_again(copy, finished):
    cut = copy / "batches" / "00001.npz"
    data = cut.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    result = _sweep(*TWO, "--out", copy, "--resume")
    assert result.returncode == 0, result.stderr
    assert "1 done before, 1 to run" in result.stderr
    assert (copy / "batches" / "00001.npz.damaged").read_bytes() == data[: len(data) // 2]
    with np.load(copy / "results.npz") as new, np.load(finished / "results.npz") as old:
        assert np.array_equal(new["lift_time_s"], old["lift_time_s"], equal_nan=True)


def test_stale_temporaries_of_a_killed_run_are_removed_and_nothing_else(copy):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a process id that no longer runs, as a SIGKILLed sweep's
    ours = [
        copy / f".results.csv.{dead.pid}-ab3_x9yz.partial",
        copy / f".trade_off.png.{dead.pid}-qwertyui.partial.png",  # --no-plots now: not written again
        copy / "batches" / f".00001.npz.{dead.pid}-k2j4h5g6.partial.npz",
    ]
    kept = [
        copy / ".results.csv.mine",  # not a name the sweep makes
        copy / f".notes.txt.{dead.pid}-abcdefgh.partial",  # not one of the sweep's files
        copy / f".results.npz.{os.getpid()}-abcdefgh.partial.npz",  # its writer still runs
    ]
    for path in ours + kept:
        path.write_bytes(b"half")
    result = _sweep(*TWO, "--out", copy, "--resume")
    assert result.returncode == 0, result.stderr
    assert not any(p.exists() for p in ours)
    assert all(p.read_bytes() == b"half" for p in kept)
    assert result.stderr.count("left unfinished by an earlier run that was stopped") == 3


def test_a_stopped_sweep_leaves_no_temporary_of_its_own_and_another_writers_stays(tmp_path):
    """A stop can land between a batch's temporary and the writer that removes it on failure (the
    context manager not yet entered): the line a stopped sweep ends with removes what this
    process left half-written, and nothing of a process that still runs."""
    from boom_hydraulics.sweeps.runner import Reached
    from boom_hydraulics.sweeps.store import SweepStore

    store = SweepStore(tmp_path / "s", resume=False)
    store.save(0, {"point": np.arange(2)})
    mine = store.batches / f".00001.npz.{os.getpid()}-k2j4h5g6.partial.npz"
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        theirs = store.batches / f".00002.npz.{other.pid}-abcdefgh.partial.npz"
        for path in (mine, theirs):
            path.write_bytes(b"half")
        reached = Reached()
        reached.out, reached.store = store.folder, store
        line = reached.interrupted("interrupted (Ctrl-C)", lambda out: "boom-sweep --resume")
        assert "1 batches are stored" in line
        assert not mine.exists() and theirs.read_bytes() == b"half"
    finally:
        other.kill()
        other.wait()


def test_a_billion_points_are_refused_at_once_with_their_size(tmp_path):
    result = _sweep("--vary", "piston_diameter=0.04:0.08:1000000000", "--out", tmp_path / "s")
    _one_error(result, 2, "1000000000 points need about 5.12 TB of memory")
    assert not (tmp_path / "s").exists()


def test_a_large_sweep_says_its_size_before_planning_and_stops_on_ctrl_c(tmp_path):
    out = tmp_path / "s"
    args = ["--vary", "payload=0:200:400", "--vary", "piston_diameter=0.04:0.08:100", "--out", out]
    process = subprocess.Popen([BOOM_SWEEP, *map(str, args)], stderr=subprocess.PIPE, text=True)
    first = process.stderr.readline()  # planning 40 000 points takes seconds: the size comes first
    assert first.startswith("boom-sweep: planning 40000 points in 40 or more batches"), first
    assert "to run: 2e+08 steps" in first
    process.send_signal(signal.SIGINT)
    rest = process.stderr.read()
    assert process.wait(timeout=60) == 130
    assert rest == "boom-sweep: error: interrupted (Ctrl-C) before a batch finished; nothing was stored\n"
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--duration", "1e300"], "--duration 1e+300 s is longer than a scenario's commands can span"),
        (["--set", "time_step_s=1e-12", "--duration", "1e4"], "cannot count more than 2**53 steps"),
        (["--duration", "-1"], "--duration must be a positive number"),
        (["--duration", "inf"], "--duration must be a finite number"),
        (["--lift-angle-deg", "nan"], "--lift-angle-deg must be a finite number"),
        (["--max-pressure-pa", "inf"], "--max-pressure-pa must be a finite number"),
        (["--scheduler-timeout", "nan"], "--scheduler-timeout must be a finite number"),
        (["--samples", "-5"], "--samples must be a whole number >= 0"),
        (["--sample", "lhs", "--vary", "payload=0:9", "--samples", "3", "--seed", "-1"], "--seed must be"),
        (["--every", "0"], "--every must be a whole number >= 1"),
        (["--batch-size", "-3"], "--batch-size must be a whole number >= 1"),
        (["--workers", "0"], "--workers must be a whole number >= 1"),
        (["--workers", "100000"], "--workers 100000: this machine has"),
        (["--top", "0"], "--top must be a whole number >= 1"),
        (["--vary", "payload=0:200:-4"], "COUNT must be a whole number >= 1"),
        (["--vary", "payload=0:inf:4"], "not a finite number"),
        (["--samples", "1e9"], "invalid int value"),
    ],
)
def test_an_absurd_number_is_one_line_exit_2_and_no_folder(tmp_path, args, words):
    result = _sweep(*args, "--out", tmp_path / "s")
    _one_error(result, 2, words)
    assert not (tmp_path / "s").exists()


def test_an_unknown_parameter_points_to_a_command_that_lists_them(tmp_path):
    result = _sweep("--vary", "piston_size=0.04,0.06", "--out", tmp_path / "s")
    _one_error(result, 2, "(boom_sim --help lists them)")
    if BOOM_SIM_NODE is not None:  # and that command does list them
        listing = subprocess.run([BOOM_SIM_NODE, "--help"], capture_output=True, text=True, timeout=60)
        assert listing.returncode == 0 and "piston_diameter_m" in listing.stdout


@pytest.mark.parametrize("where", [[], ["--workers", "2"]], ids=["this process", "local Dask cluster"])
def test_ctrl_c_in_a_long_batch_ends_with_one_line_and_stores_nothing_half_made(tmp_path, where):
    """A batch of a day-long lift cannot finish: Ctrl-C lands inside it (or while the cluster starts)."""
    out = tmp_path / "s"
    args = ["--vary", "payload=0,100", "--duration", "1e5", *where, "--out", out]
    process = subprocess.Popen([BOOM_SWEEP, *map(str, args)], stderr=subprocess.PIPE, text=True)
    line = process.stderr.readline()
    assert "0 done before, " in line and " to run " in line, line
    process.send_signal(signal.SIGINT)
    rest = process.stderr.read()
    assert process.wait(timeout=60) == 130
    assert rest == "boom-sweep: error: interrupted (Ctrl-C) before a batch finished; nothing was stored\n"
    assert not out.exists()


def _alive_in_session(session: int) -> list[str]:
    """The processes of ``session`` still running (not zombies): their command lines."""
    alive = []
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, ValueError):
            continue  # (not a process, or one that ended meanwhile)
        state, _, _, sid = stat.rsplit(")", 1)[1].split()[:4]
        if int(sid) == session and state != "Z":
            alive.append(cmdline)
    return alive


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("to", ["the terminal's group", "boom-sweep alone"])
def test_ctrl_c_while_batches_run_leaves_no_plotting_process_behind(tmp_path, to):
    """The process that draws the plots is forked before the batches: a Ctrl-C from the terminal
    (to every process of the group) or to boom-sweep alone (kill -INT) ends it too, with the
    sweep's one line and nothing written."""
    out = tmp_path / "s"
    args = ["--vary", "payload=0,100", "--duration", "1e5", "--out", out]
    process = subprocess.Popen([BOOM_SWEEP, *map(str, args)], stderr=subprocess.PIPE, text=True,
                               start_new_session=True)  # fmt: skip
    try:
        line = process.stderr.readline()  # (said once the plots' process is forked)
        assert "0 done before, " in line, line
        assert len(_alive_in_session(process.pid)) == 2  # boom-sweep and the process that will plot
        if to == "boom-sweep alone":
            process.send_signal(signal.SIGINT)
        else:
            os.killpg(process.pid, signal.SIGINT)
        _, rest = process.communicate(timeout=60)  # (a process left holding stderr fails this, not hangs)
        assert process.returncode == 130
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
    assert rest == "boom-sweep: error: interrupted (Ctrl-C) before a batch finished; nothing was stored\n"
    assert _alive_in_session(process.pid) == []
    assert not out.exists()


@pytest.mark.parametrize("where", ["planning", "a batch", "nowhere"])
def test_the_plots_process_is_stopped_when_the_sweep_fails_and_waited_for_when_it_ends(tmp_path, monkeypatch, where):
    """Forked before the plan, the process that draws the plots is stopped by whatever ends
    the sweep early (here a failure; a Ctrl-C takes the same path), and otherwise handed the
    table and waited for."""
    from boom_hydraulics.errors import BoomHydraulicsError
    from boom_hydraulics.sweeps import plotter, sweep

    events = []

    class Drawer:  # (plotter.Plotter's calls, without the fork)
        def draw(self, table, columns, folder) -> None:
            events.append("draw")

        def wait(self) -> list[str]:
            events.append("wait")
            return []

        def stop(self) -> None:
            events.append("stop")

    def failing(*args, **kwargs):
        raise BoomHydraulicsError(f"a failure in {where}")

    monkeypatch.setattr(plotter, "start", Drawer)
    if where != "nowhere":
        monkeypatch.setattr(sweep, "plan" if where == "planning" else "run_batch", failing)
    result = _sweep(*TWO[:-1], "--out", tmp_path / "s")
    if where == "nowhere":
        assert (result.returncode, events) == (0, ["draw", "wait"]), result.stderr
    else:
        last = result.stderr.splitlines()[-1]  # (after the plan's line, where the batches failed)
        assert (result.returncode, last) == (1, f"boom-sweep: error: a failure in {where}"), result.stderr
        assert events == ["stop"]


#: A sweep whose trade-off figure is drawn until a Ctrl-C comes (the test waits for the figure).
_DRAWING_TILL_CTRL_C = """
import sys, time
from pathlib import Path
from boom_hydraulics.cli import sweep
from boom_hydraulics.sweeps import plots

def drawing(*args):
    Path(sys.argv[2]).touch()
    while True:
        time.sleep(0.01)

plots.trade_off = drawing  # (the plots' processes are forked from this one: theirs too)
sys.exit(sweep.main(["--vary", "payload=0,150", "--duration", "0.5", "--lift-angle-deg", "8", "--out", sys.argv[1]]))
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_ctrl_c_while_the_plots_are_drawn_ends_every_process_and_keeps_no_half_plot(tmp_path):
    out, drawing = tmp_path / "s", tmp_path / "drawing"
    process = subprocess.Popen(
        [sys.executable, "-c", _DRAWING_TILL_CTRL_C, str(out), str(drawing)], stderr=subprocess.PIPE, text=True,
        start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not drawing.exists():  # the figure is being drawn
            assert process.poll() is None and time.monotonic() < deadline, process.communicate()
            time.sleep(0.01)
        os.killpg(process.pid, signal.SIGINT)  # as the terminal's Ctrl-C
        _, stderr = process.communicate(timeout=60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
    last = stderr.strip().splitlines()[-1]
    assert process.returncode == 130 and "Traceback" not in stderr, stderr
    assert last.startswith("boom-sweep: error: interrupted (Ctrl-C); 1 of 1 batches are stored in "), last
    assert _alive_in_session(process.pid) == []
    assert not [p.name for p in out.iterdir() if "partial" in p.name]  # no half-written figure
    assert (out / "results.csv").exists()  # the table was written beside the plots
