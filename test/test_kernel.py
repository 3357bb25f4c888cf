"""The one run loop plugged three ways: the compiled run kernel, the loop over the compiled steps
(a Python command) and the loop interpreted give the same run."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis import metrics as analysis
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, from_mapping, with_updates
from boom_hydraulics.solve import accelerate, commands
from boom_hydraulics.solve.batch import run_sets
from boom_hydraulics.solve.simulation import OUTPUT_NAMES, Simulator
from boom_hydraulics.sweeps import sweep
from boom_hydraulics.sweeps.sampling import parse_axis

pytestmark = pytest.mark.skipif(not accelerate.available(), reason="numba not installed")

CASES = {
    "lift-hold-lower": (Parameters(), "steps:0=1,0.6=0,0.9=-0.5"),
    "sine-euler": (with_updates(Parameters(), method="euler", substeps=4), "sine:0.2,0.6,2"),
    "closed-loop": (Parameters(), "angle:0=25,0.8=15"),
    "paper-ramp": (config.load(CONFIG / "paper_fig10.yaml"), "ramp:0=0,0.3=1"),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_the_run_kernel_the_loop_over_compiled_steps_and_the_interpreted_loop_agree(case):
    base, profile = CASES[case]
    params = from_mapping(commands.parse_profile(profile), base=base)
    duration, every = 1.2, 7  # 1200 steps: samples every 7 and at the end
    command = commands.from_parameters(params)
    runs = run_sets([params], duration, command, every, store=True)
    assert runs is not None and math.isnan(runs.failed_at_s[0])
    kernel = runs.columns(0)
    python_command = (lambda t, y: command(t, y)) if case == "closed-loop" else (lambda t: command(t))
    python_command.feedback = case == "closed-loop"  # a Python function: the kernel cannot take it
    stepped = Simulator(params, jit=True).run(duration, python_command, every)
    interpreted = Simulator(params, jit=False).run(duration, commands.from_parameters(params), every)
    assert len(kernel["t"]) == len(stepped) == 1 + 1200 // 7 + 1
    for name in OUTPUT_NAMES:  # the same compiled steps, commands and samples: bit for bit
        assert np.array_equal(kernel[name], stepped[name], equal_nan=True), name
    for name in ("q1", "v", "p1", "u", "supply_energy"):
        scale = max(np.max(np.abs(interpreted[name])), 1e-9)
        assert np.max(np.abs(kernel[name] - interpreted[name])) <= 1e-9 * scale, name
    assert runs.most_substeps[0] == stepped.most_substeps
    # the metrics taken while running equal those of the stored run
    expected = analysis.metrics(stepped.columns, params=params)
    for name, value in runs.metrics.items():
        both_nan = math.isnan(value[0]) and math.isnan(expected[name])
        assert both_nan or math.isclose(value[0], expected[name], rel_tol=1e-12, abs_tol=1e-15), name
    closed_loop = np.isfinite([expected[k] for k in ("target_overshoot_deg", "target_error_deg")])
    assert closed_loop.all() == (case == "closed-loop")


def test_a_sweep_without_numba_gives_the_compiled_sweeps_table(monkeypatch):
    axes = [parse_axis("piston_diameter=0.04,0.063"), parse_axis("payload=0,150")]
    plan = sweep.plan(sweep.request([("default", Parameters())], axes, duration_s=1.5, lift_angle_deg=10.0))
    (batch,) = plan.batches
    compiled = sweep.run_batch(batch)
    monkeypatch.setenv("BOOM_HYDRAULICS_JIT", "0")
    numpy_batch = sweep.run_batch(batch)
    assert compiled["status"].tolist() == numpy_batch["status"].tolist() == ["ok", "ok", "incomplete", "incomplete"]
    for name in sweep.METRIC_NAMES:
        np.testing.assert_allclose(compiled[name], numpy_batch[name], rtol=1e-9, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("case", ["closed-loop", "sine-euler"])
def test_a_run_split_into_slices_equals_the_run_in_one_call(case, monkeypatch):
    from boom_hydraulics.solve import batch

    base, profile = CASES[case]
    params = from_mapping(commands.parse_profile(profile), base=base)
    sets = [params, with_updates(params, payload_mass_kg=150.0)]

    def run(first: int, growth: int):
        monkeypatch.setattr(batch, "FIRST_SLICE", first)
        monkeypatch.setattr(batch, "next_slice", lambda passes, seconds, most: min(most, growth))
        return batch.run_sets(sets, 1.2, commands.from_parameters(params), 7, store=True)

    whole = run(10**9, 10**9)  # one kernel call over every step
    sliced = run(3, 11)  # 110 calls of 11 steps: the controller, command and samples carried over
    for k in range(len(sets)):
        for name in OUTPUT_NAMES:
            assert np.array_equal(whole.columns(k)[name], sliced.columns(k)[name], equal_nan=True), name
    for name, values in whole.metrics.items():
        assert np.array_equal(values, sliced.metrics[name], equal_nan=True), name
    for field in ("failed_at_s", "failed_why", "most_substeps", "states", "samples"):
        assert np.array_equal(getattr(whole, field), getattr(sliced, field), equal_nan=True), field


def test_a_failing_set_in_slices_stops_where_it_does_in_one_call(monkeypatch):
    from boom_hydraulics.solve import batch

    fig8 = config.load(CONFIG / "paper_fig8.yaml")
    whole = run_sets([fig8], 3.0, commands.constant(1.0), every=10, store=True)
    monkeypatch.setattr(batch, "next_slice", lambda passes, seconds, most: 13)
    sliced = run_sets([fig8], 3.0, commands.constant(1.0), every=10, store=True)
    assert sliced.failed_at_s[0] == whole.failed_at_s[0] and sliced.samples[0] == whole.samples[0]
    assert np.array_equal(sliced.columns(0)["q1"], whole.columns(0)["q1"])


@pytest.mark.parametrize("n_sets", [1, 3])
def test_every_command_gives_the_run_kernel_arguments_of_one_type(n_sets):
    """A profile and a position loop hand the run kernel the same numba types, so that one
    compile serves both: a read-only knot array (broadcast for one set) was another type, and
    each first closed-loop run compiled the whole kernel again (15 s)."""
    numba = pytest.importorskip("numba")
    loop = commands.from_parameters(from_mapping(commands.parse_profile("angle:0=25,0.8=15"), base=Parameters()))
    kinds = [commands.constant(0.5), commands.steps([0.0, 0.6], [1.0, 0.0]), loop]
    types = [tuple(numba.typeof(field) for field in c.kernel_command(n_sets)) for c in kinds]
    assert types[0] == types[1] == types[2]
