"""Long runs as a user meets them: Ctrl-C and SIGTERM stop them within a second, a full or
read-only disk and absurd sizes give one line, and what a stopped run left is cleaned up."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from conftest import CONFIG, run_tool

BOOM_SIM = shutil.which("boom-sim")
pytestmark = pytest.mark.skipif(BOOM_SIM is None, reason="boom-sim not on PATH (run through tools/with-env)")
ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="mounting a small tmpfs needs root")
#: A failure guard only: the tests wait for events, and a run stops within a second of a signal.
GUARD_S = 60


def _run(*args) -> subprocess.CompletedProcess:
    """boom-sim's main in this process (conftest.run_tool); the signals go to real processes."""
    return run_tool("boom-sim", *args)


def _one_error_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("boom-sim: error: ") and "Traceback" not in stderr, stderr
    return lines[0]


def _default_sigint() -> None:
    """The child takes Ctrl-C even where this test run was started with SIGINT ignored (a
    background job of a script): Python then installs its KeyboardInterrupt handler."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for_rows(folder: Path, process: subprocess.Popen) -> Path:
    """The run's temporary CSV, once rows have reached it (the run is in its stepping loop)."""
    deadline = time.monotonic() + GUARD_S
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()
        partial = [p for p in folder.iterdir() if p.name.endswith(".partial")]
        if partial and partial[0].stat().st_size > 10_000:
            return partial[0]
        time.sleep(0.05)
    raise AssertionError("the run wrote no rows within the guard time")


@pytest.mark.parametrize(
    ("sig", "status", "word"), [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")]
)
def test_a_signal_stops_a_long_run_with_one_line_and_no_file(tmp_path, sig, status, word):
    out = tmp_path / "long.csv"
    process = subprocess.Popen(
        [BOOM_SIM, "run", "--duration", "1e6", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_sigint,
    )
    try:
        partial = _wait_for_rows(tmp_path, process)
        assert partial.name.startswith(".long.csv.")  # streamed under a temporary name
        process.send_signal(sig)
        stdout, stderr = process.communicate(timeout=GUARD_S)
    finally:
        process.kill()
        process.wait()
    assert process.returncode == status
    assert word in _one_error_line(stderr) and stdout == ""
    assert list(tmp_path.iterdir()) == []  # neither the CSV nor its temporary file


@ROOT_ONLY
@pytest.mark.parametrize(
    "args",
    [
        ["run", "--duration", "5"],
        ["statics", "--points", "20000"],
        ["urdf"],
    ],
    ids=["run", "statics", "urdf"],
)
@pytest.mark.parametrize("disk", ["full", "read-only"])
def test_a_full_or_read_only_disk_names_the_file_asked_for(tmp_path, args, disk):
    mount = tmp_path / "disk"
    mount.mkdir()
    options = "size=64k" if disk == "full" else "ro,size=64k"
    subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(mount)], check=True)
    try:
        if disk == "full":
            with (mount / "filler").open("wb", buffering=0) as filler:  # the user's file, filling the disk
                with pytest.raises(OSError):
                    while True:
                        filler.write(b"x" * 4096)
        before = sorted(p.name for p in mount.iterdir())
        out = mount / "result.out"
        result = _run(*args, "--config", CONFIG / "default.yaml", "--out", out)
        assert result.returncode == 1
        line = _one_error_line(result.stderr)
        assert f"error: {out}: " in line and ".partial" not in line
        assert ("disk is full" if disk == "full" else "Read-only file system") in line
        assert sorted(p.name for p in mount.iterdir()) == before  # nothing of this run is left
    finally:
        subprocess.run(["umount", str(mount)], check=True)


@ROOT_ONLY
def test_boom_resim_onto_a_read_only_disk_names_the_out_asked_for(tmp_path):
    """The bag it would write is staged in a hidden folder beside --out: the error line named
    that '.new.xxxxxxxx.partial', a name the user never gave."""
    from machine_bags import record_node

    bag = record_node(tmp_path / "bag", duration_s=0.5)
    mount = tmp_path / "disk"
    mount.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(mount)], check=True)
    try:
        out = mount / "new"
        result = run_tool("boom-resim", bag, "--out", out)
        assert result.returncode == 1, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
        assert lines[0].startswith(f"boom-resim: error: {out}: Read-only file system"), lines
        assert ".partial" not in lines[0]
        assert list(mount.iterdir()) == []
    finally:
        subprocess.run(["umount", str(mount)], check=True)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "--duration", "inf"], "--duration must be a positive number of seconds"),
        (["run", "--duration", "nan"], "--duration must be a positive number of seconds"),
        (["run", "--duration", "-5"], "--duration must be a positive number of seconds"),
        (["run", "--duration", "1e300"], "more than a run can take"),
        (["run", "--duration", "1", "--dt", "nan"], "time_step_s"),
        (["run", "--duration", "1", "--set", "payload_mass_kg=nan"], "payload_mass_kg"),
        (["statics", "--points", "1000000000000"], "of memory, more than the"),
    ],
)
def test_absurd_sizes_and_nan_inputs_are_refused_up_front(tmp_path, args, message):
    out = tmp_path / "never.csv"
    result = _run(*args, "--out", out)
    assert result.returncode == 2
    assert message in _one_error_line(result.stderr)
    assert list(tmp_path.iterdir()) == []


def _dead_pid() -> int:
    """The id of a process that has ended (a short-lived child, waited for)."""
    child = subprocess.Popen(["true"])
    child.wait()
    return child.pid


def test_the_leftovers_of_a_killed_run_are_removed_by_the_next_with_a_note(tmp_path):
    out = tmp_path / "run.csv"
    stale = tmp_path / f".run.csv.{_dead_pid()}-abc123_x.partial"
    stale.write_text("half a table")
    live = tmp_path / f".run.csv.{os.getpid()}-abc123_x.partial"  # a run still writing: not ours to remove
    live.write_text("being written")
    other = tmp_path / ".run.csv.notes.partial"  # not a name boom-sim makes
    other.write_text("the user's")
    result = _run("run", "--duration", "0.2", "--out", out)
    assert result.returncode == 0, result.stderr
    assert (
        result.stderr.strip()
        == f"boom-sim: note: removed {stale}, the unfinished run.csv of an earlier run that was stopped"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, live.name, other.name])


def test_a_sigkilled_run_leaves_a_file_that_the_next_run_removes(tmp_path):
    out = tmp_path / "long.csv"
    process = subprocess.Popen([BOOM_SIM, "run", "--duration", "1e6", "--out", str(out)], stderr=subprocess.PIPE)
    try:
        partial = _wait_for_rows(tmp_path, process)
    finally:
        process.kill()
        process.wait()
    assert partial.exists()  # SIGKILL: nobody cleaned up
    result = _run("run", "--duration", "0.2", "--out", out)
    assert result.returncode == 0 and f"removed {partial}" in result.stderr
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_strict_json_has_null_for_metrics_without_a_value():
    from boom_hydraulics.files import json_text

    text = json_text({"oscillation_hz": float("nan"), "settling_s": float("inf"), "lift_m": 0.25, "ok": True})
    assert json.loads(text, parse_constant=lambda name: pytest.fail(f"{name} is not JSON")) == {
        "oscillation_hz": None,
        "settling_s": None,
        "lift_m": 0.25,
        "ok": True,
    }


@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning")  # no "Exception ignored" either
def test_a_ctrl_c_that_a_finalizer_swallowed_still_stops_a_run_at_its_next_slice(capsys):
    """Python drops an exception raised in ``__del__`` (as when Ctrl-C lands while the compiled
    kernel's LLVM objects are disposed of); the run loop raises the recorded signal again, and
    the user sees the one line of an interrupted tool, no traceback."""
    from boom_hydraulics.model.parameters import Parameters
    from boom_hydraulics.programs import run_main
    from boom_hydraulics.solve.batch import run_sets
    from boom_hydraulics.solve.commands import constant

    class Finalized:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs here, inside the finalizer: its exception is dropped
                pass

    ran = []

    def body() -> int:
        Finalized()
        ran.append("went on after the signal")
        run_sets([Parameters()], 0.5, constant(1.0), jit=False)
        ran.append("the run ended")
        return 0

    assert run_main("test", body) == 130
    assert ran == ["went on after the signal"]
    said = capsys.readouterr().err
    assert said == "test: error: interrupted (Ctrl-C); stopped, and what it was writing was not kept\n"


def test_llvmlite_objects_a_stop_left_half_made_are_no_traceback_and_nothing_else_is_hidden(monkeypatch):
    """A Ctrl-C (twice, in CI) that cut an llvmlite object's close() or __init__ between two
    statements left it without an attribute; its finalizer then printed "Exception ignored ...
    AttributeError" after the node's one line. Once a stop has come that is hidden; before a
    stop, and any other finalizer's error, still reach the user."""
    import sys

    from llvmlite import binding as llvm
    from llvmlite.binding.ffi import OutputString

    from boom_hydraulics.programs import dropped_interrupts_unreported

    seen: list = []
    monkeypatch.setattr(sys, "unraisablehook", seen.append)

    def half_closed_then_collected() -> None:
        ref = llvm.get_global_context()
        del ref._as_parameter_  # where a signal's exception cut ObjectRef.detach short
        del ref  # its __del__ runs close() again

    def half_made_then_collected() -> None:
        OutputString.__new__(OutputString)  # an __init__ cut before it set _ptr; __del__ reads it

    class Failing:
        def __del__(self) -> None:
            raise AttributeError("'Failing' object has no attribute '_as_parameter_'")

    stopped = False
    with dropped_interrupts_unreported(lambda: stopped):
        half_closed_then_collected()  # no stop yet: shown
        stopped = True
        half_closed_then_collected()  # after a stop: hidden
        half_made_then_collected()  # hidden too
        Failing()  # the same error from our own code: shown
    half_made_then_collected()  # outside: shown
    assert [(d.object.__qualname__.split(".")[-2:], d.exc_type) for d in seen] == [
        (["ObjectRef", "__del__"], AttributeError),
        (["Failing", "__del__"], AttributeError),
        (["OutputString", "__del__"], AttributeError),
    ]


#: A program started with Ctrl-C pressed while its modules load: the finder below is asked for
#: the program's first module of this package (after boom_hydraulics.entry_points, the console
#: script's own) and sends SIGINT there; the handler's KeyboardInterrupt comes out of the import.
_CTRL_C_WHILE_LOADING = """
import os, signal, sys
from importlib.metadata import entry_points

class CtrlCWhileLoading:
    def find_spec(self, name, path=None, target=None):
        if name.startswith("boom_hydraulics.") and name != "boom_hydraulics.entry_points":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
            while True:  # Python runs the handler here
                pass
        return None

signal.signal(signal.SIGINT, signal.default_int_handler)
(entry,) = entry_points(group="console_scripts", name=sys.argv[1])
main = entry.load()
sys.meta_path.insert(0, CtrlCWhileLoading())
status = main()
os.kill(os.getpid(), signal.SIGINT)  # a second Ctrl-C (a terminal's and ros2 launch's come together)
for _ in range(1000):  # a handler would run here
    pass
sys.exit(status)
"""


def _console_scripts() -> list[str]:
    from importlib.metadata import entry_points

    return sorted(e.name for e in entry_points(group="console_scripts") if e.value.startswith("boom_hydraulics."))


@pytest.mark.parametrize("tool", _console_scripts())
def test_ctrl_c_while_a_program_loads_its_modules_ends_in_one_line(tool):
    """numpy, numba and rclpy take a second or two to load (more on a busy machine): a Ctrl-C
    then is one line and the documented status (130; the node: 0, as for any stop), not an
    import's traceback; and a second Ctrl-C after it changes nothing."""
    import sys

    done = subprocess.run([sys.executable, "-c", _CTRL_C_WHILE_LOADING, tool], capture_output=True, text=True,
                          timeout=GUARD_S)  # fmt: skip
    out = done.stdout + done.stderr
    if tool == "boom_sim":
        assert (done.returncode, out.strip()) == (0, "boom_sim: stopped while starting; nothing was recorded"), out
    else:
        line = f"{tool}: error: interrupted (Ctrl-C) while starting; nothing was written"
        assert (done.returncode, out.strip()) == (130, line), out


#: A Ctrl-C that the code it lands in turns into another exception, as matplotlib's drawing
#: once made a ValueError ('Invalid bounding box') of one while a sweep plotted. The plots are
#: drawn in the process boom-sweep forks (sweeps.plotter), which ends as stopped, not failed.
_CTRL_C_TURNED_INTO_AN_ERROR = """
import os, signal, sys
from pathlib import Path
from boom_hydraulics.cli import sweep
from boom_hydraulics.sweeps import plots

def drawing(*args, **kwargs):
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10**7):  # the handler raises here
            pass
    except KeyboardInterrupt:
        raise ValueError("Invalid bounding box") from None
    raise AssertionError("the signal did not come")

plots.plot_all = drawing if sys.argv[2] == "signal" else lambda *a, **k: 1 / 0
signal.signal(signal.SIGINT, signal.default_int_handler)
sys.exit(sweep.main(["--config", sys.argv[1], "--vary", "payload=0,150", "--duration", "0.2", "--out", sys.argv[3]]))
"""


@pytest.mark.parametrize("cause", ["signal", "bug"])
def test_an_error_a_ctrl_c_turned_into_is_the_stop_and_a_bug_stays_a_bug(tmp_path, cause):
    """A Ctrl-C lands in whatever code runs; code that makes another exception of it (matplotlib)
    must not turn the stop into a traceback: the sweep's one line, its stored batch and resume
    command, exit 130. The same error without a signal is a bug, and is not hidden. Either way
    the batches' table is written (the plots write it first, and they never began)."""
    import sys

    out = tmp_path / "sweep"
    script = [sys.executable, "-c", _CTRL_C_TURNED_INTO_AN_ERROR, str(CONFIG / "default.yaml"), cause, str(out)]
    done = subprocess.run(script, capture_output=True, text=True, timeout=GUARD_S)
    if cause == "signal":
        last = done.stderr.strip().splitlines()[-1]
        assert done.returncode == 130 and "Traceback" not in done.stderr, done.stderr
        assert last.startswith("boom-sweep: error: interrupted (Ctrl-C); 1 of 1 batches are stored in "), last
        assert last.endswith(" --resume"), last
    else:
        assert done.returncode == 1 and "ZeroDivisionError" in done.stderr, done.stderr
    assert (out / "results.csv").exists()  # the table, though the plots stopped before it was written


_TAKEN_AS_ITS_END = """
import os, signal, sys
from boom_hydraulics.programs import run_main, stop_handled

def body():
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10**7):  # the handler raises here
            pass
    except KeyboardInterrupt:
        if sys.argv[1] == "handled":
            stop_handled()  # as boom-replay and boom-sim live do: a Ctrl-C is how they end
    raise KeyError("a bug after the stop")

signal.signal(signal.SIGINT, signal.default_int_handler)
sys.exit(run_main("tool", body))
"""


@pytest.mark.parametrize("way", ["handled", "not handled"])
def test_a_bug_after_a_ctrl_c_that_a_program_took_as_its_end_is_not_hidden(way):
    """boom-replay and boom-sim live catch a Ctrl-C and end normally: an error after it is a bug,
    and shows as one; a program that did not take the stop reports the stop."""
    import sys

    done = subprocess.run([sys.executable, "-c", _TAKEN_AS_ITS_END, way], capture_output=True, text=True,
                          timeout=GUARD_S)  # fmt: skip
    if way == "handled":
        assert done.returncode == 1 and "KeyError: 'a bug after the stop'" in done.stderr, done.stderr
    else:
        assert (done.returncode, done.stderr.strip()) == (
            130,
            "tool: error: interrupted (Ctrl-C); stopped, and what it was writing was not kept",
        ), done.stderr


_SECOND_CTRL_C_AFTER_THE_LINE = """
import os, signal, sys
from importlib.metadata import entry_points

signal.signal(signal.SIGINT, signal.default_int_handler)
(entry,) = entry_points(group="console_scripts", name="boom-bag-recover")
sys.argv = ["boom-bag-recover", sys.argv[1]]
status = entry.load()()
if os.environ.get("SECOND_CTRL_C"):
    os.kill(os.getpid(), signal.SIGINT)  # pressed again as the line appears
    for _ in range(10**6):
        pass
sys.exit(status)
"""


def test_a_second_ctrl_c_after_a_tools_last_line_changes_nothing(tmp_path):
    """A tool that has said its line (here boom-bag-recover's for a missing bag) ends with the
    status it decided, whatever signal comes after."""
    import sys

    missing = str(tmp_path / "no_such_bag")
    script = [sys.executable, "-c", _SECOND_CTRL_C_AFTER_THE_LINE, missing]
    runs = []
    for second in ("", "1"):
        env = {**os.environ, "SECOND_CTRL_C": second}
        runs.append(subprocess.run(script, capture_output=True, text=True, timeout=GUARD_S, env=env))
    alone, pressed = runs
    assert alone.returncode != 0 and len(alone.stderr.strip().splitlines()) == 1, alone.stderr
    assert (pressed.returncode, pressed.stderr) == (alone.returncode, alone.stderr), pressed.stderr
