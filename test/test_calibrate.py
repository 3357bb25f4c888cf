"""boom-calibrate: parameters recovered from a recorded run, what it writes, what it refuses."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from machine_bags import params_file, record_machine

from boom_hydraulics.calibration.fittable import fittable, why_not_fitted
from boom_hydraulics.cli import calibrate as cli
from boom_hydraulics.model import config

TRUTH = {"bulk_modulus_pa": 1.0e9, "orifice_diameter_m": 0.002}
NOISE = {"q1": 2e-4, "p1": 5e4, "p2": 5e4}  # 0.2 mm, 0.05 MPa: a machine's sensors


@pytest.fixture(scope="module")
def machine(tmp_path_factory):
    """A machine's bag (no run description) of a lift, hold, lower and hold with the default
    parameters: sensors at about 100 Hz, log times jittered by up to 3 ms, with noise."""
    return record_machine(tmp_path_factory.mktemp("machine") / "bag", noise=NOISE)


def test_perturbed_parameters_are_recovered_from_a_noisy_machine_bag(machine, tmp_path, capsys):
    """Bulk modulus x 0.6 and orifice x 1.2 come back within 1 %, the truth inside or near the
    95 % interval; the params file carries them and loads as boom-sim and ROS 2 load it."""
    start = params_file(tmp_path / "start.yaml", {"bulk_modulus_pa": 0.6e9, "orifice_diameter_m": 0.0024})
    out = tmp_path / "fit"
    args = [str(machine), "--config", str(start), "--fit", "bulk_modulus_pa,orifice_diameter_m", "--out", str(out)]
    assert cli.main(args) == 0
    printed = capsys.readouterr().out
    assert "bulk_modulus_pa: 6e+08 ->" in printed and "RMS residual before -> after" in printed
    assert sorted(f.name for f in out.iterdir()) == ["calibrated.yaml", "calibration.csv", "fit.png", "signals.csv"]
    fitted = config.load(out / "calibrated.yaml")
    for name, true in TRUTH.items():
        assert getattr(fitted, name) == pytest.approx(true, rel=0.01), name
    with (out / "calibration.csv").open() as handle:
        rows = list(csv.reader(handle))
    for row in rows[1:]:
        name, _, _, value, low, high, _, verdict = row
        assert verdict == "ok", row
        assert float(low) < float(value) < float(high)
        width = float(high) - float(low)
        assert abs(float(value) - TRUTH[name]) < 3 * width, row  # the noise's doing, not a bias
    rclpy_parameter = pytest.importorskip("rclpy.parameter")
    loaded = rclpy_parameter.parameter_dict_from_yaml_file(str(out / "calibrated.yaml"), use_wildcard=True)
    assert loaded["bulk_modulus_pa"].value.double_value == pytest.approx(fitted.bulk_modulus_pa)


def test_a_boom_sim_bag_is_fitted_from_its_own_parameters_with_a_changed_start(tmp_path, capsys):
    bag = record_machine(tmp_path / "run", {"payload_mass_kg": 50.0}, duration_s=2.0, jitter_s=0.0, describe=True)
    out = tmp_path / "fit"
    assert cli.main([str(bag), "--set", "payload_mass_kg=90", "--fit", "payload_mass_kg", "--out", str(out)]) == 0
    assert config.load(out / "calibrated.yaml").payload_mass_kg == pytest.approx(50.0, rel=1e-3)
    assert "payload_mass_kg: 90 ->" in capsys.readouterr().out


def test_the_fittable_parameters_are_the_plants_numbers_less_the_chain_and_the_start():
    names = fittable()
    assert {"bulk_modulus_pa", "orifice_diameter_m", "coulomb_friction_n", "payload_mass_kg"} <= set(names)
    assert not {"a_m", "cylinder_max_length_m", "initial_length_m", "time_step_s", "mode"} & set(names)
    assert "kinematic chain" in why_not_fitted("boom_length_m")


@pytest.fixture(scope="module")
def still(tmp_path_factory):
    """A short bag with no commands at all."""
    return record_machine(tmp_path_factory.mktemp("still") / "bag", commands=(), duration_s=0.3)


@pytest.mark.parametrize(
    ("bag", "args", "message"),
    [
        ("still", ["--fit", "bulk_modulus_pa"], "holds no valve commands"),
        ("machine", ["--fit", "a_m"], "--fit a_m: cannot be fitted: it is part of the kinematic chain"),
        ("machine", ["--fit", "bulk_modulus"], "--fit bulk_modulus: unknown parameter; did you mean bulk_modulus_pa"),
        ("machine", ["--fit", "orifice_diameter_m,density_kg_m3"], "no signal tells them apart"),
        ("machine", ["--fit", "bulk_modulus_pa", "--weight", "v=2"], "--weight v: not one of the signals"),
        ("machine", ["--fit", "mode"], "--fit mode: cannot be fitted: it is a choice"),
    ],
)
def test_what_cannot_be_fitted_is_one_line_and_nothing_written(request, tmp_path, capsys, bag, args, message):
    folder = request.getfixturevalue(bag)
    start = params_file(tmp_path / "start.yaml", {})
    out = tmp_path / "never"
    assert cli.main([str(folder), "--config", str(start), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err, err
    assert not out.exists()


def test_a_bag_without_run_description_needs_a_config(machine, tmp_path, capsys):
    assert cli.main([str(machine), "--fit", "bulk_modulus_pa", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "has no run description (not recorded by boom_sim); give --config" in err


def test_a_machine_bag_is_read_at_the_steps_around_its_samples_with_the_values_of_every_step(machine):
    """A bag without the node's states is simulated on a grid of time steps; the fit stops to
    read the state only at the two steps around each recorded sample (jittered, three sensors),
    the two np.interp reads there: the same simulated signals, bit for bit, as reading every
    step, from fewer instants (each read of a state costs Python time that the steps between do not)."""
    from boom_hydraulics.calibration import fit
    from boom_hydraulics.resim.resimulation import Replay

    start = params_file(machine.parent / "start.yaml", {"bulk_modulus_pa": 0.8e9})
    problem = fit.prepare(machine, ["bulk_modulus_pa"], start)
    theta = [1.1]  # (a fraction of the start value)
    read = problem.simulate(theta)
    every_step = Replay(problem.run, problem.values, problem.overrides | problem.fitted_values(theta))
    t_ns, columns = [], {s: [] for s in problem.signals}
    for stamp_ns, outputs in every_step:
        t_ns.append(stamp_ns)
        for s in problem.signals:
            columns[s].append(outputs[s])
    t = (np.array(t_ns) - problem.run.clock_origin_ns).astype(float) * 1e-9
    assert np.allclose(np.diff(t), problem.start.time_step_s)  # every step
    for s in problem.signals:
        whole = np.interp(problem.times_s[s], t, columns[s], left=np.nan, right=np.nan)
        assert np.array_equal(read[s], whole, equal_nan=True), s
        assert np.isfinite(read[s]).sum() > 0.95 * len(read[s])  # (not a comparison of nan: all but the ends)
    around = Replay(problem.run, problem.values, problem.overrides, problem.read_at_s)
    assert len(around.instants) <= 2 * len(problem.read_at_s) < len(every_step.instants)
