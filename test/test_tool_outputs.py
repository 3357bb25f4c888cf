"""What the tools write, and what they leave alone: the examples a user lost data with."""

from __future__ import annotations

import csv
import shutil
import subprocess

import numpy as np
import pytest
from conftest import CONFIG, run_tool

pytest.importorskip("rclpy")
from rclpy.serialization import serialize_message

from boom_hydraulics.bags.reading import read_drive_states
from boom_hydraulics.bags.recording import BagRecorder, Topic
from boom_hydraulics_msgs.msg import DriveState

NAMES = ("boom-analyze", "boom-study", "boom-sim", "boom-sweep", "boom-resim", "boom-replay", "boom-bag-recover")
TOOLS = {name: shutil.which(name) for name in (*NAMES, "boom-demo")}
pytestmark = pytest.mark.skipif(None in TOOLS.values(), reason="run through tools/with-env")
EPOCH_NS = 1_795_398_778_106_328_251  # a real stamp: float seconds since the epoch resolve 238 ns


def _bag(folder, n: int = 60) -> None:
    """DriveStates at 10 ms on the epoch clock, with a lift so that the metrics have a rise."""
    with BagRecorder(folder, [Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")]) as rec:
        for i in range(n):
            ns = EPOCH_NS + i * 10_000_001  # 10 ms and 1 ns: the nanosecond must survive
            msg = DriveState(rod_position_m=1.3 + 1e-3 * i, valve_command=1.0 if i > 5 else 0.0)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
            msg.piston_pressure_pa = msg.rod_pressure_pa = 1e5
            rec.write("/drive_state", ns, serialize_message(msg))


def _run(tool: str, *args, cwd=None) -> subprocess.CompletedProcess:
    """The tool's main in this process (conftest.run_tool); what a new process does is
    test_help_of_boom_sim_needs_no_ros_graph's and the demo's."""
    return run_tool(tool, *args, cwd=cwd)


def test_analyze_keeps_what_the_user_kept_in_its_folder(tmp_path):
    _bag(tmp_path / "run1")
    out = tmp_path / "results"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "run1.csv").write_text("an old result")
    result = _run("boom-analyze", tmp_path / "run1", "--out", out)
    assert result.returncode == 0, result.stderr
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "run1.csv").read_text() != "an old result"  # its own file, replaced
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["notes.txt", "run1.csv", "run1.npz", "run1.metrics.json", "dynamics.png", "drive.png"]
    )


def test_analyze_of_a_run_that_never_lifted_says_so_in_words(tmp_path):
    """A bag of the boom at rest (the node started and stopped, no command): its line says the
    boom never reached 90 % of a lift, where it printed 'nan s'."""
    with BagRecorder(tmp_path / "rest", [Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")]) as rec:
        for i in range(20):
            msg = DriveState(rod_position_m=1.3, piston_pressure_pa=1e5, rod_pressure_pa=1e5)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(EPOCH_NS + i * 10_000_000, 10**9)
            rec.write("/drive_state", EPOCH_NS + i * 10_000_000, serialize_message(msg))
    result = _run("boom-analyze", tmp_path / "rest")
    assert result.returncode == 0, result.stderr
    line = result.stdout.splitlines()[0]
    assert "lift 0.000 m, 90 % never reached, peak speed 0.000 m/s" in line, line
    assert "nan" not in line.lower(), line


def test_analyze_into_the_current_folder_touches_nothing_else(tmp_path):
    _bag(tmp_path / "bags" / "run1")
    work = tmp_path / "work"
    work.mkdir()
    (work / "thesis.tex").write_text("years of work")
    (work / "data").mkdir()
    result = _run("boom-analyze", tmp_path / "bags" / "run1", "--out", ".", cwd=work)
    assert result.returncode == 0, result.stderr
    assert (work / "thesis.tex").read_text() == "years of work" and (work / "data").is_dir()
    assert (work / "run1.csv").is_file()


def test_analyze_of_the_current_folder_writes_beside_it(tmp_path):
    _bag(tmp_path / "run1")
    result = _run("boom-analyze", ".", cwd=tmp_path / "run1")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "run1.analysis" / "run1.csv").is_file()


@pytest.mark.parametrize("out", ["run2", "."])
def test_an_output_that_is_or_holds_the_input_is_refused(tmp_path, out):
    _bag(tmp_path / "run2")
    before = sorted(p.name for p in (tmp_path / "run2").iterdir())
    result = _run("boom-analyze", "run2", "--out", out, cwd=tmp_path)
    assert result.returncode == 2 and "input" in result.stderr and len(result.stderr.splitlines()) == 1
    assert sorted(p.name for p in (tmp_path / "run2").iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run2"]


def test_study_writes_its_figures_beside_others(tmp_path, monkeypatch):
    """(Its solver study shortened to two runs of 0.05 s: the files are the point here, every
    figure of the full study is test_studies'.)"""
    from boom_hydraulics.analysis import studies

    solver_study = studies.solver_study
    monkeypatch.setattr(
        studies, "solver_study", lambda p, s, steps: solver_study(p, 0.05, {"euler": [1e-3], "rk4": [1e-3]})
    )
    out = tmp_path / "figures"
    out.mkdir()
    (out / "sweep_trade_off.png").write_bytes(b"the README's figure")
    result = _run("boom-study", "paper", "--out", out, "--duration", "0.3")
    assert result.returncode == 0, result.stderr
    assert (out / "sweep_trade_off.png").read_bytes() == b"the README's figure"
    assert {"fig3_angles.png", "fig8.png", "solver_study.csv", "statics.csv"} <= {p.name for p in out.iterdir()}
    with (out / "statics.csv").open() as handle:
        header = next(csv.reader(handle))
    assert header[:4] == ["q1 [m]", "alpha [rad]", "phi [rad]", "static_force [N]"]  # as boom-sim statics


def test_sim_and_sweep_refuse_to_write_over_their_config(tmp_path):
    config_file = tmp_path / "mine.yaml"
    shutil.copy(CONFIG / "default.yaml", config_file)
    text = config_file.read_text()
    run = _run("boom-sim", "run", "--config", config_file, "--duration", "0.1", "--out", config_file)
    assert run.returncode == 2 and "is the input" in run.stderr
    sweep = _run("boom-sweep", "--config", config_file, "--vary", "payload=0,50", "--out", tmp_path)
    assert sweep.returncode == 2 and "holds the input" in sweep.stderr
    assert config_file.read_text() == text and sorted(p.name for p in tmp_path.iterdir()) == ["mine.yaml"]


def test_csv_time_keeps_every_nanosecond(tmp_path):
    _bag(tmp_path / "run1")
    signals = read_drive_states(tmp_path / "run1")  # no recorded origin: t = 0 at the first message
    expected = np.arange(60) * 10_000_001 * 1e-9
    assert np.max(np.abs(signals["t"] - expected)) < 1e-12  # epoch floats would be off by ~1e-7
    assert signals["t"][0] == 0.0
    command = read_drive_states(tmp_path / "run1", align="command")["t"]
    assert command[6] == 0.0 and command[0] < 0  # t = 0 where the valve first opens


@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_help_is_plain_text_and_names_each_default_once(tool):
    result = _run(tool, "--help")
    assert result.returncode == 0, result.stderr
    assert "``" not in result.stdout and "usage:" in result.stdout
    for line in result.stdout.splitlines():
        assert line.count("default") <= 1, line


def test_help_of_boom_sim_needs_no_ros_graph():
    result = subprocess.run([shutil.which("boom_sim"), "-h"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0 and "record_folder" in result.stdout


@pytest.mark.parametrize(
    ("tool", "args", "message"),
    [
        ("boom-study", ["paper", "--duration", "-1"], "--duration must be a number of simulated seconds"),
        ("boom-demo", ["--duration", "-5"], "--duration must be a positive number of seconds, got -5"),
    ],
)
def test_bad_durations_are_one_line_before_anything_runs(tmp_path, tool, args, message):
    result = _run(tool, *args, cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip().splitlines() == [f"{tool}: error: {result.stderr.split('error: ', 1)[1].strip()}"]
    assert message in result.stderr
    assert list(tmp_path.iterdir()) == []  # no node started, no bag, no figures


@pytest.mark.skipif(shutil.which("boom_sim") is None, reason="run through tools/with-env")
def test_the_demo_drives_the_node_records_and_analyses_the_run(tmp_path):
    """make run: the node in its own process, the scenario on valve_command, the bag analysed."""
    result = subprocess.run(
        [TOOLS["boom-demo"], "--params-file", CONFIG / "default.yaml", "--duration", "3", "--bags", tmp_path],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    table = [line.split() for line in lines if line.strip() and line.split()[0].replace(".", "").isdigit()]
    assert len(table) >= 5  # the state printed every half second
    assert float(table[-1][2]) > float(table[0][2]) + 0.1  # q1: the valve opened, the boom rose
    (bag,) = [p for p in tmp_path.iterdir() if p.is_dir() and p.name.endswith("_boom_sim")]
    assert any(line.startswith(f"boom_sim: bag {bag}") for line in lines)
    assert f"boom-analyze: results in {bag.with_name(bag.name + '.analysis')}" in result.stdout
    assert (bag.with_name(bag.name + ".analysis") / "dynamics.png").is_file()
