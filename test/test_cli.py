"""boom-sim: outputs, and one-line errors without traceback; the first test through its real
entry point (a new process), the others through its main in this process."""

from __future__ import annotations

import csv
import shutil
import subprocess

import numpy as np
import pytest
from conftest import CONFIG, run_tool

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config

BOOM_SIM = shutil.which("boom-sim")
pytestmark = pytest.mark.skipif(BOOM_SIM is None, reason="boom-sim not on PATH (run through tools/with-env)")


def _run(*args: object) -> subprocess.CompletedProcess:
    """boom-sim's main in this process (conftest.run_tool)."""
    return run_tool("boom-sim", *args)


def _read(path):
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array(rows[1:], dtype=float)


def test_a_run_says_when_it_compiles_the_run_kernel_first(tmp_path, monkeypatch):
    """Where numba's cache lacks the run kernel, the run sits a minute compiling: it says so
    first, on stderr; with the kernel cached (as after this process ran once), nothing."""
    from boom_hydraulics import jit
    from boom_hydraulics.solve import accelerate

    args = ["run", "--config", CONFIG / "default.yaml", "--duration", "0.05"]
    assert _run(*args, "--out", tmp_path / "first.csv").returncode == 0
    if accelerate.available():  # the cache holds what the run called (read from numba's own index)
        assert [jit.in_cache(k) for k in accelerate.run_kernels("physical", "rk4")] == [True]
    cached = _run(*args, "--out", tmp_path / "cached.csv")
    assert cached.returncode == 0 and "not compiled" not in cached.stderr, cached.stderr
    monkeypatch.setattr(jit, "in_cache", lambda entry: False)
    cold = _run(*args, "--out", tmp_path / "cold.csv")
    line = "boom-sim: the physical model's rk4 is not compiled on this machine yet: compiling it for this run takes"
    assert cold.returncode == 0 and line in cold.stderr, cold.stderr


def test_run_writes_a_row_per_step_with_named_unit_columns(tmp_path):
    out = tmp_path / "run.csv"
    result = subprocess.run(
        [BOOM_SIM, "run", "--config", CONFIG / "default.yaml", "--duration", "0.5", "--out", out],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    header, data = _read(out)
    for column in (
        "t [s]",
        "q1 [m]",
        "v [m/s]",
        "a [m/s^2]",
        "p1 [Pa]",
        "p2 [Pa]",
        "alpha [rad]",
        "u [1]",
        "f_hyd [N]",
    ):
        assert column in header
    assert len(data) == 501
    t, q1 = data[:, header.index("t [s]")], data[:, header.index("q1 [m]")]
    assert t[-1] == pytest.approx(0.5) and q1[-1] > q1[0]  # the default command opens the valve


def test_a_run_whose_battery_cannot_give_what_the_drive_asks_warns_and_its_rows_say_when(tmp_path):
    """48 V behind 0.288 ohm gives at most U^2 / (4 R) = 2 kW (eq. D11): enough for the idling
    drive, not for the lift the valve opens at 0.1 s. The run ends (status 0), its CSV flags the
    rows from the opening on, and one line on stderr counts them; a battery that copes says nothing."""
    args = ["run", "--config", CONFIG / "default.yaml", "--duration", "0.3", "--profile", "steps:0=0,0.1=1"]
    weak = _run(*args, "--set", "battery_resistance_ohm=0.288", "--out", tmp_path / "weak.csv")
    assert weak.returncode == 0, weak.stderr
    header, data = _read(tmp_path / "weak.csv")
    flagged = data[:, header.index("battery_overloaded [bool]")] == 1.0
    t = data[:, header.index("t [s]")]
    assert flagged.any() and not flagged[t < 0.1].any()
    warning = (
        f"boom-sim: warning: the battery could not give the power the drive asked in {flagged.sum()} of the 301 rows"
    )
    assert [line for line in weak.stderr.splitlines() if line.startswith("boom-sim: warning")] == [
        warning + ' (battery_overloaded; docs/model.md, "Battery"): its energy ledger does not close there; '
        "raise battery_voltage_v or lower battery_resistance_ohm"
    ]
    fine = _run(*args, "--out", tmp_path / "fine.csv")
    assert fine.returncode == 0 and "warning" not in fine.stderr, fine.stderr
    assert not _read(tmp_path / "fine.csv")[1][:, header.index("battery_overloaded [bool]")].any()


def test_run_options_profile_set_method_every(tmp_path):
    out = tmp_path / "cycle.csv"
    result = _run(
        "run",
        "--config",
        CONFIG / "default.yaml",
        "--duration",
        "2",
        "--every",
        "10",
        "--profile",
        "steps:0=1,1=-1",
        "--set",
        "piston_diameter_m=0.063",
        "--set",
        "rod_diameter_m=0.036",
        "--method",
        "euler",
        "--dt",
        "2e-4",
        "--out",
        out,
    )
    assert result.returncode == 0, result.stderr
    header, data = _read(out)
    assert len(data) == 1001
    u, q1 = data[:, header.index("u [1]")], data[:, header.index("q1 [m]")]
    t = data[:, header.index("t [s]")]
    assert set(u) == {1.0, -1.0}
    top = q1[np.argmin(np.abs(t - 1.0))]
    assert top > q1[0] + 0.05 and q1[-1] < top - 0.05  # up, then down again


def test_statics_covers_the_open_stroke_for_each_diameter(tmp_path):
    out = tmp_path / "statics.csv"
    result = _run("statics", "--config", CONFIG / "default.yaml", "--diameters", "0.04,0.08", "--out", out)
    assert result.returncode == 0, result.stderr
    header, data = _read(out)
    assert header[-2:] == ["holding_pressure_D40mm [Pa]", "holding_pressure_D80mm [Pa]"]
    assert 1.0 < data[0, 0] < 1.01 and 1.79 < data[-1, 0] < 1.8
    assert np.allclose(data[:, -2], 4 * data[:, -1])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "--duration", "1", "--set", "piston_diameter=0.05"], "unknown parameter 'piston_diameter'"),
        (["run", "--duration", "1", "--set", "rod_diameter_m=0.05"], "must be smaller than piston_diameter_m"),
        (["run", "--duration", "-1"], "--duration must be a positive number"),
        (["run", "--duration", "1", "--profile", "steps:0=1,oops"], "--profile 'steps:0=1,oops'"),
        (["run", "--duration", "1", "--config", "/nonexistent.yaml"], "/nonexistent.yaml: no such file"),
        (["run", "--duration", "1", "--method", "heun"], "invalid choice: 'heun'"),
        (["statics", "--diameters", "0.04,x"], "--diameters expects comma-separated metres"),
        # a value given on the command line is named as given there, not blamed on the config file
        (
            ["run", "--duration", "1", "--config", CONFIG / "default.yaml", "--set", "bulk_modulus_pa=inf"],
            "boom-sim: error: bulk_modulus_pa on the command line: parameter 'bulk_modulus_pa' must be a finite "
            "number, got 'inf'",
        ),
        (
            ["run", "--duration", "1", "--config", CONFIG / "default.yaml", "--set", "bulk_modulus_pa=-1"],
            "bulk_modulus_pa on the command line: parameter 'bulk_modulus_pa'",
        ),
        (
            ["run", "--duration", "1", "--config", CONFIG / "default.yaml", "--set", "rod_diameter_m=0.05"],
            f"{CONFIG / 'default.yaml'} with rod_diameter_m on the command line: rod_diameter_m (0.05 m) must be",
        ),
        # without a config file too
        (["run", "--duration", "1", "--set", "bulk_modulus_pa=-1"], "bulk_modulus_pa on the command line: parameter"),
    ],
)
def test_bad_input_gives_one_line_and_no_file(tmp_path, args, message):
    out = tmp_path / "never.csv"
    result = _run(*args, "--out", out)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.stderr
    assert not out.exists()


def test_run_that_leaves_the_geometry_fails_cleanly(tmp_path):
    out = tmp_path / "fig8.csv"
    result = _run("run", "--config", CONFIG / "paper_fig8.yaml", "--duration", "3", "--out", out)
    assert result.returncode == 1
    assert "rod is about to leave the valid geometry" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists() and not list(tmp_path.iterdir())  # no partial CSV either


def test_malformed_yaml_is_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("boom_sim:\n  ros__parameters:\n    a_m: [0.4\n")
    result = _run("run", "--config", bad, "--duration", "1", "--out", tmp_path / "x.csv")
    assert result.returncode == 2 and "malformed YAML at line" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # PyYAML took the last of two equal keys without a word
        (
            "/**:\n  ros__parameters:\n    payload_mass_kg: 10.0\n    payload_mass_kg: 20.0\n",
            "malformed YAML at line 4, column 5: key 'payload_mass_kg' is given twice (lines 3 and 4); keep one",
        ),
        # a RecursionError traceback
        ("a: " + "[" * 100_000 + "]" * 100_000 + "\n", "malformed YAML: it is nested deeper than can be read"),
        # read for minutes into gigabytes before its line; one byte past the limit is refused at once
        (" " * (config.MAX_FILE_BYTES + 1), "is larger than a params file may be (1 MiB)"),
    ],
)
def test_a_params_file_that_cannot_be_one_is_one_line(tmp_path, text, message):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    result = _run("run", "--config", bad, "--duration", "1", "--out", tmp_path / "x.csv")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not (tmp_path / "x.csv").exists()


def test_a_params_file_at_the_size_limit_is_read(tmp_path):
    text = "/**:\n  ros__parameters:\n    payload_mass_kg: 20.0\n"
    padded = tmp_path / "padded.yaml"
    padded.write_text(text + "#" * (config.MAX_FILE_BYTES - len(text) - 1) + "\n")
    assert padded.stat().st_size == config.MAX_FILE_BYTES
    assert config.load(padded).payload_mass_kg == 20.0


def test_a_params_file_with_a_yaml_merge_key_is_read(tmp_path):
    """'<<: *anchor' merges a mapping's keys (not a key given twice): read as YAML reads it."""
    merged = tmp_path / "merged.yaml"
    merged.write_text(
        "base: &b {payload_mass_kg: 60.0}\n/**:\n  ros__parameters:\n    <<: *b\n    boom_mass_kg: 120.0\n"
    )
    params = config.load(merged)
    assert (params.payload_mass_kg, params.boom_mass_kg) == (60.0, 120.0)


def test_a_params_file_over_the_limit_is_refused_for_its_size_whatever_its_last_bytes(tmp_path):
    """A character of two bytes across the limit: the size is the line, not a decoding error."""
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * (config.MAX_FILE_BYTES - 1) + "é".encode() + b"\n")
    with pytest.raises(ConfigError, match="is larger than a params file may be"):
        config.load(big)
