"""boom-sim run, statics and urdf as a user reads them (cli/sim.py): the summary lines and what
they count, the closed loop's line, the compiling notice, the progress bar on a terminal, the
one-line refusals at their limits, and the files against what the library gives. Short runs,
in this process (conftest.run_tool)."""

from __future__ import annotations

import contextlib
import csv
import io
import math
import re

import numpy as np
import pytest
from conftest import CONFIG, run_tool

from boom_hydraulics.cli import sim as cli
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.model.robot_description import urdf
from boom_hydraulics.solve import accelerate

DEFAULT = CONFIG / "default.yaml"


def _run(*args: object):
    return run_tool("boom-sim", *args)


def _read(path) -> tuple[list[str], np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array(rows[1:], dtype=float)


def _column(path, name: str) -> np.ndarray:
    header, data = _read(path)
    return data[:, header.index(name)]


def _error(result) -> str:
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    (line,) = result.stderr.strip().splitlines()
    return line


def test_a_runs_line_counts_its_rows_and_gives_q1_at_its_first_and_last_row(tmp_path):
    out = tmp_path / "run.csv"
    result = _run("run", "--config", DEFAULT, "--duration", "0.05", "--every", "10", "--out", out)
    assert result.returncode == 0 and result.stderr == "", result.stderr
    q1 = _column(out, "q1 [m]")
    assert len(q1) == 6 and q1[-1] > q1[0]  # t = 0, 0.01, ... 0.05: the valve opens from the start
    assert np.array_equal(_column(out, "t [s]"), np.round(np.arange(6) * 0.01, 12))
    assert result.stdout == f"{out}: 6 rows, physical mode, rk4 dt=0.001 s, q1 {q1[0]:.4f} -> {q1[-1]:.4f} m\n"


def test_the_csv_has_a_column_per_output_named_with_its_unit(tmp_path):
    from boom_hydraulics.solve.simulation import OUTPUTS

    out = tmp_path / "run.csv"
    assert _run("run", "--duration", "0.003", "--out", out).returncode == 0
    header, data = _read(out)
    assert header == [f"{name} [{unit}]" for name, unit, _ in OUTPUTS]
    assert data.shape == (4, len(OUTPUTS))


@pytest.mark.parametrize(
    ("args", "note"),
    [
        (["--method", "euler"], ", up to 2 substeps per step (stability bound)"),
        (["--method", "ros2", "--dt", "0.02"], ", up to 4 substeps per step (failed steps taken again in halves)"),
        (["--method", "rk4"], ""),  # the least substeps it was given: nothing to say
    ],
)
def test_a_run_that_took_more_substeps_than_asked_says_how_many_and_why(tmp_path, args, note):
    out = tmp_path / "run.csv"
    result = _run("run", "--config", DEFAULT, "--duration", "0.2", *args, "--out", out)
    assert result.returncode == 0, result.stderr
    assert result.stdout.endswith(" m" + note + "\n"), result.stdout


def test_a_closed_loop_set_in_the_parameters_has_its_line_too(tmp_path):
    """command_profile read from the config or --set (a string of its own, not the literal)."""
    sets = ["command_profile=angle", "command_times_s=[0.0]", "command_angles_rad=[0.3]"]
    result = _run("run", "--duration", "0.01", *(a for s in sets for a in ("--set", s)), "--out", tmp_path / "r.csv")
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[1].startswith(f"closed loop: 8.47 -> {math.degrees(0.3):.2f} deg, ")


def test_the_closed_loops_line_gives_the_start_of_its_first_move_and_whether_it_settled(tmp_path):
    moving = _run("run", "--config", DEFAULT, "--duration", "0.6", "--profile", "angle:0.5=20,0.55=25",
                  "--out", tmp_path / "short.csv")  # fmt: skip
    assert moving.returncode == 0, moving.stderr
    t, alpha = _column(tmp_path / "short.csv", "t [s]"), _column(tmp_path / "short.csv", "alpha [rad]")
    start = math.degrees(alpha[np.searchsorted(t, 0.5)])  # the first sample of the move (at 0.5 s)
    assert f"{start:.2f}" != f"{math.degrees(alpha[0]):.2f}"  # the boom sagged before it: not the run's start
    line = moving.stdout.splitlines()[1]
    assert line.startswith(f"closed loop: {start:.2f} -> 20.00 deg, not settled within 2 %, overshoot ")
    assert re.fullmatch(r".*, overshoot -?\d+\.\d{3} deg, final error -?\d+\.\d{3} deg", line), line
    settled = _run("run", "--config", DEFAULT, "--duration", "4", "--target-angle-deg", "20", "--every", "100",
                   "--out", tmp_path / "long.csv")  # fmt: skip
    assert settled.returncode == 0, settled.stderr
    line = settled.stdout.splitlines()[1]
    assert re.fullmatch(
        r"closed loop: 8\.47 -> 20\.00 deg, settled within 2 % in \d\.\d{3} s, overshoot \d\.\d{3} deg, "
        r"final error -?0\.\d{3} deg",
        line,
    ), line
    assert len(settled.stdout.splitlines()) == 2
    open_loop = _run("run", "--duration", "0.01", "--out", tmp_path / "open.csv")
    assert "closed loop" not in open_loop.stdout and len(open_loop.stdout.splitlines()) == 1


def test_a_work_cycle_runs_its_scenarios_moves(tmp_path):
    from boom_hydraulics.solve import commands

    out = tmp_path / "cycle.csv"
    result = _run("run", "--config", DEFAULT, "--profile", "loader", "--duration", "0.01", "--out", out)
    assert result.returncode == 0, result.stderr
    first = math.degrees(commands.scenario("loader", 0.0, config.load(DEFAULT))["command_angles_rad"][0])
    assert result.stdout.splitlines()[1].startswith(f"closed loop: 8.47 -> {first:.2f} deg, not settled")


def test_a_run_says_first_when_it_will_compile_and_nothing_where_it_will_not(tmp_path, monkeypatch):
    monkeypatch.setattr(accelerate, "not_in_cache", lambda kernels: True)
    cold = _run("run", "--set", "method=euler", "--duration", "0.01", "--out", tmp_path / "cold.csv")
    assert cold.returncode == 0, cold.stderr
    notice = accelerate.compiling_notice("physical", "euler", "this run")
    assert cold.stderr.splitlines() == [f"boom-sim: {notice}"]
    monkeypatch.setattr(accelerate, "not_in_cache", lambda kernels: False)
    warm = _run("run", "--set", "method=euler", "--duration", "0.01", "--out", tmp_path / "warm.csv")
    assert warm.returncode == 0 and warm.stderr == "", warm.stderr


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_on_a_terminal_a_run_shows_its_simulated_seconds_done(tmp_path):
    err = _Terminal()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert cli.main(["run", "--duration", "0.05", "--out", str(tmp_path / "run.csv")]) == 0
    last = err.getvalue().replace("\r", "\n").strip().splitlines()[-1]
    assert re.fullmatch(r"boom-sim: 100%\|\S+\| 0\.05/0\.05 s simulated \[.*<.*\]", last), last


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--every", "0"], "boom-sim: error: --every must be >= 1, got 0"),
        (["--every", "-3"], "boom-sim: error: --every must be >= 1, got -3"),
        (
            ["--profile", "constant:1", "--target-angle-deg", "20"],
            "boom-sim: error: give either --profile or --target-angle-deg, not both",
        ),
        (
            ["--target-angle-deg", "nan"],
            "boom-sim: error: --target-angle-deg must be a finite angle in degrees, got nan",
        ),
        (
            ["--target-angle-deg=-inf"],
            "boom-sim: error: --target-angle-deg must be a finite angle in degrees, got -inf",
        ),
    ],
)
def test_run_options_out_of_their_range_are_one_line(tmp_path, args, message):
    out = tmp_path / "never.csv"
    assert _error(_run("run", "--duration", "0.01", *args, "--out", out)) == message
    assert list(tmp_path.iterdir()) == []


def test_every_one_and_a_target_angle_alone_run(tmp_path):
    assert _run("run", "--duration", "0.002", "--every", "1", "--out", tmp_path / "a.csv").returncode == 0
    assert len(_column(tmp_path / "a.csv", "t [s]")) == 3
    target = _run("run", "--duration", "0.002", "--target-angle-deg", "0", "--out", tmp_path / "b.csv")
    assert target.returncode == 0 and "-> 0.00 deg" in target.stdout, target.stderr


def test_statics_writes_the_librarys_table_exactly_and_counts_it(tmp_path):
    out = tmp_path / "statics.csv"
    result = _run("statics", "--config", DEFAULT, "--diameters", "0.05,,0.063,", "--points", "2", "--out", out)
    assert result.returncode == 0 and result.stderr == "", result.stderr
    assert result.stdout == f"{out}: 2 positions x 2 piston diameters\n"
    header, table = cli.statics_table(config.load(DEFAULT), [0.05, 0.063], 2)
    with open(out, newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == header
    assert rows[1:] == [[repr(float(v)) for v in row] for row in table]  # every digit: repr round-trips
    default = _run("statics", "--out", tmp_path / "default.csv")
    assert default.stdout == f"{tmp_path / 'default.csv'}: 161 positions x 3 piston diameters\n"
    assert _read(tmp_path / "default.csv")[0][-3:] == [
        "holding_pressure_D40mm [Pa]",
        "holding_pressure_D63mm [Pa]",
        "holding_pressure_D80mm [Pa]",
    ]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--points", "1"], "boom-sim: error: --points must be >= 2, got 1"),
        (["--diameters", ""], "boom-sim: error: --diameters must be positive diameters in m, got ''"),
        (["--diameters", ",,"], "boom-sim: error: --diameters must be positive diameters in m, got ',,'"),
        (["--diameters", "0.05,0"], "boom-sim: error: --diameters must be positive diameters in m, got '0.05,0'"),
        (["--diameters", "-0.05"], "boom-sim: error: --diameters must be positive diameters in m, got '-0.05'"),
        (["--diameters", "0.05,inf"], "boom-sim: error: --diameters must be positive diameters in m, got '0.05,inf'"),
        (["--diameters", "nan"], "boom-sim: error: --diameters must be positive diameters in m, got 'nan'"),
        (["--diameters", "0.05;0.06"], "boom-sim: error: --diameters expects comma-separated metres, got '0.05;0.06'"),
    ],
)
def test_statics_options_out_of_their_range_are_one_line(tmp_path, args, message):
    assert _error(_run("statics", *args, "--out", tmp_path / "never.csv")) == message
    assert list(tmp_path.iterdir()) == []


def test_urdf_writes_the_config_and_its_settings_and_names_the_joints(tmp_path):
    out = tmp_path / "crane.urdf"
    result = _run("urdf", "--config", DEFAULT, "--set", "a_m=0.5", "--out", out)
    assert result.returncode == 0 and result.stderr == "", result.stderr
    assert result.stdout == (
        f"{out}: URDF of the crane (boom_joint, cylinder_barrel_joint, cylinder_joint) with the config's dimensions\n"
    )
    expected = urdf(config.load(DEFAULT, {"a_m": 0.5}))
    assert out.read_text() == expected != urdf(Parameters())


def test_a_run_without_a_config_takes_the_defaults_and_the_options(tmp_path):
    out = tmp_path / "run.csv"
    result = _run("run", "--duration", "0.01", "--dt", "0.002", "--set", "mode=paper", "--out", out)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"{out}: 6 rows, paper mode, rk4 dt=0.002 s, q1 ")


def test_a_run_in_many_slices_counts_and_reports_them_as_one(tmp_path, monkeypatch):
    """The CSV is written a slice at a time (4 rows here instead of 8192): the line's rows and
    q1 are the whole run's, and the progress bar ends at the run's seconds."""
    from boom_hydraulics.solve import simulation

    monkeypatch.setattr(simulation, "CHUNK_ROWS", 4)  # 4 + 4 + 3 rows
    out = tmp_path / "run.csv"
    err = _Terminal()
    args = ["run", "--duration", "0.05", "--every", "5", "--set", "initial_velocity_m_s=0.1", "--out", str(out)]
    with contextlib.redirect_stdout(io.StringIO()) as stdout, contextlib.redirect_stderr(err):
        assert cli.main(args) == 0
    q1 = _column(out, "q1 [m]")
    assert len(q1) == 11 and len(set(np.round(q1, 4))) == 11  # every row's q1 tells apart at 4 digits
    assert stdout.getvalue() == f"{out}: 11 rows, physical mode, rk4 dt=0.001 s, q1 {q1[0]:.4f} -> {q1[-1]:.4f} m\n"
    last = err.getvalue().replace("\r", "\n").strip().splitlines()[-1]
    assert " 0.05/0.05 s simulated " in last, last


@pytest.mark.parametrize("chunk_rows", [8192, 1])
def test_the_closed_loops_start_is_its_first_sample_in_the_moves_window(tmp_path, monkeypatch, chunk_rows):
    """Samples every 0.5 s: a move from 0.25 s to 1.5 s starts at the sample at 0.5 s (the one
    at 1.0 s is further on its way), whatever slices the samples come in; a move from 0.6 s
    until the next at 1.0 s (or 0.9 s) has no sample (the one at 1.0 s is the next move's): the
    line says so, and how to measure it, instead of nan for its start, overshoot and error (so
    does one that starts after the last sample)."""
    from boom_hydraulics.solve import simulation

    monkeypatch.setattr(simulation, "CHUNK_ROWS", chunk_rows)
    out = tmp_path / "window.csv"
    result = _run("run", "--duration", "1.5", "--every", "500", "--profile", "angle:0.25=20,1.5=25", "--out", out)
    assert result.returncode == 0, result.stderr
    t, alpha = _column(out, "t [s]"), np.degrees(_column(out, "alpha [rad]"))
    assert list(t) == [0.0, 0.5, 1.0, 1.5]
    assert len({f"{a:.2f}" for a in alpha}) == 4  # each sample's elevation tells apart
    assert result.stdout.splitlines()[1].startswith(f"closed loop: {alpha[1]:.2f} -> 20.00 deg, ")
    for end in ("1", "0.9"):  # the next move at the next sample, or between samples
        unsampled = _run("run", "--duration", "1", "--every", "500", "--profile", f"angle:0.6=20,{end}=25",
                         "--out", tmp_path / f"unsampled_{end}.csv")  # fmt: skip
        assert unsampled.returncode == 0, unsampled.stderr
        assert unsampled.stdout.splitlines()[1] == (
            f"closed loop: the move to 20.00 deg (0.6 s to {end} s) has no sample to measure it by; "
            "sample more often (a smaller --every)"
        ), end
    last = _run(
        "run", "--duration", "0.7", "--every", "500", "--profile", "angle:0.8=20", "--out", tmp_path / "last.csv"
    )
    assert last.stdout.splitlines()[1] == (
        "closed loop: the move to 20.00 deg (from 0.8 s) has no sample to measure it by; sample more often "
        "(a smaller --every)"
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "boom-sim: error: boom-sim: the following arguments are required: command"),
        (["run", "--duration", "1"], "boom-sim: error: boom-sim run: the following arguments are required: --out"),
        (["run", "--out", "x.csv"], "boom-sim: error: boom-sim run: the following arguments are required: --duration"),
        (["statics"], "boom-sim: error: boom-sim statics: the following arguments are required: --out"),
    ],
)
def test_a_missing_command_or_required_option_is_one_line(tmp_path, args, message):
    result = run_tool("boom-sim", *args, cwd=tmp_path)
    assert _error(result) == message
    assert list(tmp_path.iterdir()) == []


def test_statics_takes_the_memory_its_table_needs_and_refuses_one_byte_less(tmp_path, monkeypatch):
    """100 positions x 2 diameters hold 100 x (2 + 16) floats at the peak: 14 400 bytes."""
    from boom_hydraulics.solve import simulation

    needed = 8 * 100 * (2 + cli.STATICS_WORK_COLUMNS)
    assert needed == 14_400
    args = ["statics", "--diameters", "0.05,0.06", "--points", "100"]
    monkeypatch.setattr(simulation, "available_memory", lambda: needed)
    assert _run(*args, "--out", tmp_path / "fits.csv").returncode == 0
    monkeypatch.setattr(simulation, "available_memory", lambda: needed - 1)
    expected = (
        f"boom-sim: error: --points 100 with 2 diameters needs {simulation.size_text(needed)} of memory, more than "
        f"the {simulation.size_text(needed - 1)} available; "
        "ask for fewer points (a few thousand draw every curve smooth)"
    )
    assert _error(_run(*args, "--out", tmp_path / "never.csv")) == expected
    assert not (tmp_path / "never.csv").exists()
