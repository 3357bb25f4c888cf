"""boom-sim fmu: the physical drive as an FMI 2.0 co-simulation FMU that needs no Python,
run by fmpy in a Python that has fmpy alone (test/fmu_host.py, test/fmpy_alone.py) and by a
C host with no Python at all (test/fmu_c_host.c), and held to boom-sim's own runs."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIG
from fmpy_alone import fmpy_alone

from boom_hydraulics import jit
from boom_hydraulics.fmu import native
from boom_hydraulics.model import physical
from boom_hydraulics.model.geometry import static_rod_force_of
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve.simulation import Simulator

BOOM_SIM = shutil.which("boom-sim")
pytestmark = pytest.mark.skipif(BOOM_SIM is None, reason="boom-sim not on PATH (run through tools/with-env)")

HOST = Path(__file__).with_name("fmu_host.py")
C_HOST = Path(__file__).with_name("fmu_c_host.c")
#: The parameter the host sets through FMI before one of its cycles.
SUPPLY_PA = 12.0e6
#: boom-sim's profile of the host's cycle: lift 3 s, hold 2 s, lower 3 s, hold 1 s.
CYCLE = "steps:0=1,3=0,5=-1,8=0"
OUTPUTS = ("q1", "v", "f_hyd", "p1", "p2", "alpha", "power", "supply_energy")
#: The external rod forces of the host's scenarios (fmu_host.FORCE_CYCLE_N, FORCE_HELD_N), N.
FORCE_CYCLE_N = -2000.0
FORCE_HELD_N = 2000.0
#: fmi2Discard, the status of a refused step.
DISCARD = 2


def _boom_sim(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([BOOM_SIM, *map(str, args)], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fmu") / "boom_drive.fmu"
    result = _boom_sim("fmu", "--config", CONFIG / "default.yaml", "--out", out)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"{out}: FMI 2.0 co-simulation FMU")
    return out


@pytest.fixture(scope="module")
def report(fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """What the host saw, in a Python of its own that has fmpy and its requirements alone
    (isolated, no site-packages): fmpy loads the FMU's binary there."""
    alone = fmpy_alone(tmp_path_factory.mktemp("fmpy_alone"))
    result = subprocess.run(
        [sys.executable, "-I", "-S", HOST, fmu, "--set", f"supply_pressure_pa={SUPPLY_PA!r}", "--path", alone],
        capture_output=True,
        text=True,
        timeout=600,
        env=_without_python(),
    )
    assert result.returncode == 0, result.stderr  # also: the host exits cleanly
    return json.loads(result.stdout)


def _without_python() -> dict[str, str]:
    """This environment without the variables that tell a Python or a loader where to look."""
    return {
        key: value
        for key, value in os.environ.items()
        if not key.startswith("PYTHON") and key not in ("LD_PRELOAD", "LD_LIBRARY_PATH", "VIRTUAL_ENV")
    }


def test_the_host_runs_it_in_a_python_that_has_fmpy_alone(report: dict) -> None:
    """The host's Python imports none of what boom-sim runs on: the FMU carries the drive."""
    assert report["isolated"] == {"numba": False, "boom_hydraulics": False, "yaml": False}
    assert len(report["cycle"]["rows"]) == 901  # ... and ran it


def _cycle_csv(folder: Path, *sets: str) -> dict[str, np.ndarray]:
    out = folder / f"cycle{len(sets)}.csv"
    extra = [a for s in sets for a in ("--set", s)]
    result = _boom_sim("run", "--config", CONFIG / "default.yaml", "--profile", CYCLE, "--duration", 9,
                       "--every", 10, *extra, "--out", out)  # fmt: skip
    assert result.returncode == 0, result.stderr
    with out.open(newline="") as handle:
        rows = list(csv.reader(handle))
    data = np.array(rows[1:], dtype=float)
    return {header.split(" ")[0]: data[:, j] for j, header in enumerate(rows[0])}


def _columns(run: dict) -> dict[str, np.ndarray]:
    rows = np.array(run["rows"])
    return {name: rows[:, j] for j, name in enumerate(run["columns"])}


def _assert_equal_runs(fmu_run: dict[str, np.ndarray], boom_sim: dict[str, np.ndarray]) -> None:
    assert len(fmu_run["t"]) == len(boom_sim["t"]) == 901
    np.testing.assert_allclose(fmu_run["t"], boom_sim["t"], rtol=0, atol=1e-9)
    for name in OUTPUTS:
        scale = max(1.0, float(np.ptp(boom_sim[name])))
        np.testing.assert_allclose(fmu_run[name], boom_sim[name], rtol=0, atol=1e-9 * scale, err_msg=name)


def test_the_model_description_validates_and_names_units(fmu: Path, report: dict) -> None:
    from fmpy import read_model_description

    assert report["validate"] == []
    description = read_model_description(str(fmu))
    variables = {v.name: v for v in description.modelVariables}
    assert {n for n, v in variables.items() if v.causality == "input"} == {"valve_command", "payload_mass_kg", "f_ext"}
    f_ext = variables["f_ext"]
    assert (f_ext.unit, f_ext.variability, float(f_ext.start)) == ("N", "continuous", 0.0)
    assert "external_rod_force_n" not in variables  # the input sets it
    assert {n for n, v in variables.items() if v.causality == "output"} == set(OUTPUTS)
    units = {name: variables[name].unit for name in (*OUTPUTS, "bulk_modulus_pa", "viscous_friction_n_s_m")}
    assert units == {"q1": "m", "v": "m/s", "f_hyd": "N", "p1": "Pa", "p2": "Pa", "alpha": "rad", "power": "W",
                     "supply_energy": "J", "bulk_modulus_pa": "Pa", "viscous_friction_n_s_m": "N.s/m"}  # fmt: skip
    base = {u.name: u.baseUnit for u in description.unitDefinitions}
    assert (base["Pa"].kg, base["Pa"].m, base["Pa"].s) == (1, -1, -2)  # what a tool converts by
    leakage = base[variables["valve_leakage_m3_s_pa"].unit]  # m^3/(s Pa)
    assert (leakage.kg, leakage.m, leakage.s) == (-1, 4, 1)
    capacity = base[variables["battery_capacity_kwh"].unit]  # the battery's: 1 kWh is 3.6 MJ
    assert (capacity.kg, capacity.m, capacity.s, capacity.factor) == (1, 2, -2, 3.6e6)
    volt = base[variables["battery_voltage_v"].unit]
    assert (volt.kg, volt.m, volt.s, volt.A) == (1, 2, -3, -1)
    assert variables["bulk_modulus_pa"].variability == "tunable"
    assert variables["initial_length_m"].variability == "fixed"
    assert (variables["drive"].variability, variables["drive"].start) == ("fixed", "pressure_compensated")
    assert (variables["method"].causality, variables["method"].variability) == ("calculatedParameter", "fixed")
    assert float(variables["supply_pressure_pa"].start) == 16.0e6  # the config's value
    assert "mode" not in variables  # the physical drive only


def test_the_model_description_offers_the_units_a_fluid_power_engineer_reads(fmu: Path) -> None:
    from fmpy import read_model_description

    description = read_model_description(str(fmu))
    variables = {v.name: v for v in description.modelVariables}
    shown = {name: variables[name].displayUnit for name in ("p1", "q1", "alpha")}
    assert shown == {"p1": "bar", "q1": "mm", "alpha": "deg"}
    assert variables["pump_max_flow_m3_s"].displayUnit == "L/min"
    factors = {(u.name, d.name): d.factor for u in description.unitDefinitions for d in u.displayUnits}
    assert factors[("Pa", "bar")] == 1e-5 and factors[("m3/s", "L/min")] == 6e4
    assert factors[("m", "mm")] == 1e3 and factors[("rad", "deg")] == pytest.approx(57.29577951308232)


def test_a_lift_hold_lower_cycle_equals_boom_sims_run(report: dict, tmp_path: Path) -> None:
    run = _columns(report["cycle"])
    _assert_equal_runs(run, _cycle_csv(tmp_path))
    assert run["q1"].max() - run["q1"][0] > 0.3  # it lifted ...
    assert run["q1"][-1] < run["q1"][0]  # ... and lowered the boom onto its end stop


def test_a_parameter_set_through_fmi_takes_effect(report: dict, tmp_path: Path) -> None:
    run, plain = _columns(report["cycle_set"]), _columns(report["cycle"])
    _assert_equal_runs(run, _cycle_csv(tmp_path, f"supply_pressure_pa={SUPPLY_PA!r}"))
    at_one_s = 100
    assert run["q1"][at_one_s] < plain["q1"][at_one_s] - 0.01  # a lower supply pressure lifts slower


def test_a_tunable_parameter_applies_from_the_next_step(report: dict) -> None:
    """The supply pressure lowered after 0.5 s of lifting: the FMU goes on as the Simulator
    does with the same change between its steps, and lifts less far than at 16 MPa."""
    sim = Simulator(Parameters())
    sim.step(1.0, 500)
    sim.set_parameters(with_updates(sim.params, supply_pressure_pa=10.0e6))
    sim.step(1.0, 500)
    expected = sim.outputs()
    got = dict(zip(("t", *OUTPUTS), report["tunable"]["after"]))
    for name in OUTPUTS:
        assert got[name] == pytest.approx(expected[name], rel=1e-9, abs=1e-9), name
    unchanged = Simulator(Parameters())
    unchanged.step(1.0, 1000)
    assert got["q1"] < unchanged.outputs()["q1"] - 0.01


def test_a_payload_taken_on_is_carried_by_the_rod(report: dict) -> None:
    """Over the last second of each hold the rod force is, on average (the oil column still
    rings), the static force of eq. 6 for the payload, to within the seals' breakaway friction."""
    params = Parameters()
    forces = {}
    for key, payload_kg in (("held", 50.0), ("loaded", 150.0)):
        rows = np.array(report["payload"][key])
        force, q1 = rows[:, 1 + OUTPUTS.index("f_hyd")].mean(), rows[:, 1 + OUTPUTS.index("q1")].mean()
        static = static_rod_force_of(with_updates(params, payload_mass_kg=payload_kg), q1)
        assert abs(force - static) < params.static_friction_n, key
        forces[key] = force
    assert forces["loaded"] > 1.9 * forces["held"]  # 100 kg more at the tip: twice the rod force


def test_a_run_with_an_external_rod_force_equals_boom_sims_run_with_it(report: dict, tmp_path: Path) -> None:
    """The f_ext input held over a whole cycle is boom-sim's external_rod_force_n; pushing the rod
    in (a heavier load), it lifts less far in the first second than without."""
    run, plain = _columns(report["cycle_force"]), _columns(report["cycle"])
    _assert_equal_runs(run, _cycle_csv(tmp_path, f"external_rod_force_n={FORCE_CYCLE_N!r}"))
    at_one_s = 100
    assert run["q1"][at_one_s] < plain["q1"][at_one_s] - 0.005


def test_an_external_force_on_the_held_boom_is_taken_off_the_hydraulic_force(report: dict) -> None:
    """Over the last second of each hold (valve closed, the load-holding valve shut) the hydraulic
    rod force carries the boom's static force of eq. 6 less the external force (eq. 11 at rest),
    to within the seals' breakaway friction: pushing the rod out with FORCE_HELD_N takes that off
    the oil's force p1 S1 - p2 S2."""
    params = Parameters()
    forces = {}
    for key, external_n in (("held", 0.0), ("pushed", FORCE_HELD_N)):
        rows = np.array(report["external_force"][key])
        force, q1 = rows[:, 1 + OUTPUTS.index("f_hyd")].mean(), rows[:, 1 + OUTPUTS.index("q1")].mean()
        assert abs(force - (static_rod_force_of(params, q1) - external_n)) < params.static_friction_n, key
        forces[key] = force
    assert forces["held"] - forces["pushed"] == pytest.approx(FORCE_HELD_N, abs=2 * params.static_friction_n)


def test_refused_steps_leave_the_fmu_where_it_was(report: dict) -> None:
    refused = report["refusals"]
    odd = refused["odd_step"]
    assert odd["status"] == DISCARD and not odd["terminated"]  # a shorter step from there may go on
    assert odd["last_successful_s"] == 0.5 and odd["after"] == refused["before"]
    assert "0.0015 s" in odd["message"] and "time_step_s" in odd["message"]
    reasons = {
        "wrong_time": "the FMU is at 0.5 s",
        "zero_step": "not a whole number",
        "nan_command": "valve_command must be a finite opening",
        "nan_force": "'external_rod_force_n' must be finite",
        "bad_parameter": "piston_diameter_m",
        "fixed_parameter": "time_step_s can only be set before initialization",
    }
    for case, reason in reasons.items():
        assert refused[case]["status"] == DISCARD, case
        assert reason in refused[case]["message"], refused[case]["message"]
        assert "\n" not in refused[case]["message"]
    assert refused["after_refusals"] == refused["before"]  # none of them moved the drive
    assert refused["drifted"]["status"] == 0  # a host's time a little off the FMU's is taken as it


def test_what_the_model_refuses_the_fmu_refuses_in_the_models_words(report: dict) -> None:
    """Each value the model's parameters refuse (on its own: its range, its choices; with the
    others: the stroke, the pressures, the friction) set between two steps is refused by the FMU,
    with the line a boom-sim run gives, and leaves the drive where it was."""
    from fmu_host import MODEL_REFUSALS

    from boom_hydraulics.errors import ConfigError
    from boom_hydraulics.model import config

    exported = config.load(CONFIG / "default.yaml")
    refused = report["refusals"]["model"]
    assert set(refused) == set(MODEL_REFUSALS)
    for case, values in MODEL_REFUSALS.items():
        with pytest.raises(ConfigError) as said:
            with_updates(exported, **values)
        assert refused[case]["status"] == DISCARD, case
        assert refused[case]["message"].endswith(f"refused: {said.value}"), (case, refused[case]["message"])
    assert report["refusals"]["after_refusals"] == report["refusals"]["before"]


def test_the_method_is_the_exported_ones(report: dict) -> None:
    """Its step is compiled into the binary: a host reads it and cannot set it (fmi2Error, not Fatal)."""
    refused = report["refusals"]["set_method"]
    assert refused["status"] == 3 and "export the FMU again with boom-sim fmu --set method=" in refused["message"]
    assert refused["method"] == "rk4"


def test_the_drive_is_fixed_once_the_run_has_started(report: dict) -> None:
    refused = report["refusals"]
    drive = refused["drive"]
    assert drive["status"] == DISCARD and "drive can only be set before initialization" in drive["message"]
    assert drive["after"] == drive["before"]
    assert refused["fixed_pump"][1] != report["tunable"]["before"][1]  # chosen before: the paper's circuit runs


def test_a_time_step_too_small_for_any_step_is_refused_not_fatal(report: dict) -> None:
    tiny = report["refusals"]["tiny_time_step"]
    assert tiny["status"] == DISCARD and "not a whole number" in tiny["message"]
    assert "\n" not in tiny["message"]


def test_a_step_the_simulation_cannot_finish_is_not_taken(report: dict) -> None:
    """Refused with boom-sim's line for the same run, and the FMU stays where the step began."""
    from boom_hydraulics.errors import SimulationError
    from boom_hydraulics.model import config

    stiff = report["refusals"]["too_stiff"]
    params = with_updates(config.load(CONFIG / "default.yaml"), time_step_s=0.01, end_stop_damping_n_s_m2=1.0e15)
    with pytest.raises(SimulationError) as said:
        Simulator(params).step(1.0, 300)
    assert stiff["status"] == DISCARD and stiff["message"].endswith(f"refused: {said.value}")
    assert "too stiff at t = " in stiff["message"]
    assert stiff["last_successful_s"] == 0.0 and stiff["after"] == stiff["start"]
    assert stiff["shorter"][0] > stiff["start"][0] + 0.1  # a shorter step from there lifts the boom


def test_reset_and_terminate(report: dict) -> None:
    life = report["lifecycle"]
    assert life["again"] == life["first"]  # reset: back to rest at t = 0, the same run again
    assert life["supply_after_reset"] == 16.0e6  # ... with the exported parameters
    assert life["default"][1] > life["first"][1] + 0.01  # 16 MPa lifts faster than the 12 MPa set before
    assert life["after_terminate"]["status"] == DISCARD
    assert "terminated" in life["after_terminate"]["message"]


def test_a_host_that_is_no_python_runs_it_with_nothing_set(fmu: Path, report: dict, tmp_path: Path) -> None:
    """A C host, as OMSimulator, Simulink and fmi_adapter are, with no Python variable in its
    environment: the same lift as fmpy's, a refused step, and a clean exit."""
    compiler = shutil.which("cc")
    if compiler is None:
        pytest.skip("needs a C compiler")
    import fmpy

    host = tmp_path / "host"
    headers = Path(fmpy.__file__).parent / "c-code"  # fmpy ships the FMI 2.0 headers
    subprocess.run([compiler, "-O1", "-I", headers, "-o", host, C_HOST, "-ldl"], check=True, timeout=120)
    folder = tmp_path / "boom_drive"
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    result = subprocess.run([host, folder], env=_without_python(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr  # 0: it also exits cleanly
    said = dict(line.split(" ", 1) for line in result.stdout.splitlines() if line.startswith(("q1 ", "refused ")))
    assert float(said["q1"]) == report["lifecycle"]["default"][1]  # 1 s of lift, as in fmpy
    assert said["refused"] == str(DISCARD) and "not a whole number of the drive's time steps" in result.stdout
    linked = subprocess.run(["ldd", folder / "binaries" / "linux64" / "boom_drive.so"], capture_output=True, text=True)
    assert "python" not in linked.stdout.lower()  # no libpython: nothing of Python's is needed


# --- the command line ---------------------------------------------------------------------


def test_fmu_holds_the_drive_its_parameters_and_the_binaries(fmu: Path) -> None:
    with zipfile.ZipFile(fmu) as archive:
        names = set(archive.namelist())
        parameters = archive.read("resources/boom_drive.yaml").decode()
    assert names == {"modelDescription.xml", "binaries/linux64/boom_drive.so", "resources/boom_drive.yaml"}
    assert "    supply_pressure_pa: 16000000.0\n" in parameters


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--config", CONFIG / "paper_fig8.yaml"), "the FMU is the physical drive; mode is 'paper'"),
        (("--config", CONFIG / "default.yaml", "--set", "method=rk45"), "method 'rk45' has no fixed step"),
        (("--config", CONFIG / "default.yaml", "--set", "piston_diameter_m=-1"), "piston_diameter_m"),
    ],
)
def test_fmu_refuses_what_it_cannot_export_in_one_line(tmp_path: Path, args: tuple, message: str) -> None:
    out = tmp_path / "boom_drive.fmu"
    out.write_bytes(b"an earlier FMU")
    result = _boom_sim("fmu", *args, "--out", out)
    assert result.returncode == 2
    assert result.stderr.startswith("boom-sim: error: ") and message in result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert out.read_bytes() == b"an earlier FMU"  # whole or not at all: the old file stays
    assert sorted(p.name for p in tmp_path.iterdir()) == ["boom_drive.fmu"]  # no temporary left


def test_fmu_refuses_an_output_that_is_or_holds_its_config(tmp_path: Path) -> None:
    config = tmp_path / "drive.yaml"
    shutil.copyfile(CONFIG / "default.yaml", config)
    for out, says in ((config, "is the input"), (tmp_path, "holds the input"), (tmp_path / "x.zip", ".fmu file")):
        result = _boom_sim("fmu", "--config", config, "--out", out)
        assert result.returncode == 2, result.stderr
        assert says in result.stderr and result.stderr.count("\n") == 1
    assert config.read_bytes() == (CONFIG / "default.yaml").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.yaml"]


def test_fmu_without_a_c_compiler_says_so_in_one_line(tmp_path: Path) -> None:
    out = tmp_path / "boom_drive.fmu"
    env = dict(os.environ, CC=str(tmp_path / "no-such-cc"))
    result = subprocess.run([BOOM_SIM, "fmu", "--config", CONFIG / "default.yaml", "--out", out],
                            capture_output=True, text=True, timeout=300, env=env)  # fmt: skip
    assert result.returncode == 2
    assert result.stderr.startswith("boom-sim: error: no C compiler") and result.stderr.count("\n") == 1
    assert not out.exists()


# --- the model's own code, compiled for the FMU ------------------------------------------


@pytest.mark.parametrize(
    "changes",
    [
        {},
        {"drive": "fixed_pump", "load_holding_valve": "none", "spool_time_constant_s": 0.0},
        {"drive": "load_sensing", "payload_mass_kg": 321.0, "external_rod_force_n": -1500.0},
        {"drive": "pump_controlled", "motor_time_constant_s": 0.0, "static_friction_n": 0.0, "coulomb_friction_n": 0.0},
        {"initial_length_m": 1.6, "initial_velocity_m_s": 0.1, "supply_pressure_pa": 12.0e6},
    ],
)
def test_the_fmus_parameter_derivations_are_the_models_to_the_bit(changes: dict) -> None:
    """The constants and the state at rest the FMU derives in compiled code when a host sets a
    parameter are model.physical's own (numba compiles the functions as written, from a row
    read as the Surrogate of Parameters), for every drive."""
    params = with_updates(Parameters(), **changes)
    c, y, surrogate = _compiled_derivations(np.array(native.row_of(params)))
    assert tuple(c) == tuple(physical.constants(params))
    assert list(y) == physical.initial_state(params)
    assert [getattr(surrogate, name) for name in native.ROW] == [getattr(params, name) for name in native.ROW]


@jit.kernel(native.cache_sources())  # (cached beside the FMU's object file: compiled once, not every run)
def _compiled_derivations(row: np.ndarray) -> tuple:
    """The derivations as the FMU's code runs them, compiled once for every case above (a row
    is a float array whatever the drive): the constants, the state at rest and the Surrogate."""
    p = native.surrogate_of(row)
    return physical.constants(p), physical.initial_state(p), p
