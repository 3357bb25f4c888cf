"""A batch is its single runs through the one run loop; failing points are reported, not fatal."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, from_mapping, with_updates
from boom_hydraulics.solve import accelerate, commands, outcomes
from boom_hydraulics.solve.batch import run_sets
from boom_hydraulics.solve.simulation import OUTPUT_NAMES, simulate

JIT = [False, pytest.param(True, marks=pytest.mark.skipif(not accelerate.available(), reason="numba not installed"))]


@pytest.mark.parametrize("jit", JIT, ids=["interpreted", "compiled"])
def test_each_set_of_a_batch_runs_as_its_single_run_bit_for_bit(jit):
    base = Parameters()
    params = [
        with_updates(base, piston_diameter_m=d, rod_diameter_m=0.55 * d, payload_mass_kg=m, bulk_modulus_pa=e)
        for d, m, e in [(0.032, 0.0, 1e9), (0.05, 100.0, 1.5e9), (0.08, 200.0, 0.7e9)]
    ]
    params.append(with_updates(params[1], external_rod_force_n=-3000.0))  # the last of the constants row
    command = commands.steps([0.0, 0.5], [1.0, -0.5])
    runs = run_sets(params, 1.0, command, every=20, store=True, jit=jit)
    assert np.isnan(runs.failed_at_s).all() and runs.reasons == [None] * 4
    for k, p in enumerate(params):
        single = simulate(p, 1.0, command, every=20, jit=jit)
        for name in OUTPUT_NAMES:  # the same loop, steps, commands and samples
            assert np.array_equal(runs.columns(k)[name], single[name], equal_nan=True), name
    assert runs.columns(0)["q1"][-1] != runs.columns(2)["q1"][-1]  # the sets differ
    assert runs.columns(3)["q1"][-1] != runs.columns(1)["q1"][-1]  # ... by the external force alone too


@pytest.mark.parametrize("jit", JIT, ids=["interpreted", "compiled"])
def test_a_set_that_fails_stops_where_it_fails_with_the_reason_and_the_others_run_through(jit):
    fig8, fig9 = (config.load(CONFIG / f"paper_fig{i}.yaml") for i in (8, 9))
    runs = run_sets([fig8, fig9], 2.3, commands.constant(1.0), every=10, store=True, jit=jit)
    assert 2.0 < runs.failed_at_s[0] < 2.3 and runs.failed_why[0] == outcomes.NONFINITE  # fig. 8 leaves eq. 1
    assert 1.75 < runs.last_q1_m[0] < 1.8  # the last good state, inside (1, 1.8) m
    assert "leave the valid geometry (1, 1.8) m (paper mode has no end stops)" in runs.reasons[0]
    assert math.isnan(runs.failed_at_s[1]) and runs.failed_why[1] == outcomes.OK and runs.reasons[1] is None
    assert runs.samples[0] < runs.samples[1] == 231
    assert np.isfinite(runs.columns(0)["q1"]).all()


def test_batch_members_must_share_mode_method_and_step():
    with pytest.raises(ConfigError, match="must share time_step_s"):
        run_sets([Parameters(), with_updates(Parameters(), time_step_s=2e-3)], 0.1, commands.constant(0.0))
    with pytest.raises(ConfigError, match="fixed-step method"):
        run_sets([with_updates(Parameters(), method="rk45")], 0.1, commands.constant(0.0))


@pytest.mark.parametrize("config_file", ["default.yaml", "paper_fig8.yaml"])
def test_a_models_samples_are_its_outputs_that_the_run_metrics_take(config_file):
    """The run loop feeds the metrics from the model's ``samples`` (without computing the other
    outputs): at states across the stroke, cavitating, relieving and in motion, they are the
    outputs of SAMPLE_NAMES to the bit, so a sweep measures what a stored run shows."""
    from boom_hydraulics.model import MODELS
    from boom_hydraulics.model.outputs import SAMPLE_NAMES

    params = config.load(CONFIG / config_file)
    model = MODELS[params.mode]
    c = model.constants(params)
    rest = np.array(model.initial_state(params), dtype=float)
    rng = np.random.default_rng(7)
    picks = [OUTPUT_NAMES.index(name) for name in SAMPLE_NAMES]
    for _ in range(200):
        y = rest * rng.uniform(0.2, 1.8, rest.size) + rng.normal(0.0, 1e-3, rest.size)
        y[0] = rest[0] * rng.uniform(0.8, 1.2)  # a length across the stroke
        y[2:4] = rng.uniform(-1e6, 40e6, 2) if params.mode == "physical" else (rng.uniform(-1e6, 40e6), y[3])
        t, u = rng.uniform(0.0, 10.0), rng.uniform(-1.0, 1.0)
        outputs = model.outputs(t, y.tolist(), c, u)
        sampled = model.samples(t, y.tolist(), c, u)
        np.testing.assert_array_equal(sampled, [outputs[i] for i in picks])  # exact, NaN where no battery
    flags = [model.samples(0.0, [*rest[:2], p, p, *rest[4:]], c, 0.0) for p in (-2e6, 1e9)]
    assert flags[0][SAMPLE_NAMES.index("cavitation")] == 1.0
    if params.mode == "physical":
        assert flags[1][SAMPLE_NAMES.index("relief_open")] == 1.0


def _lock_step_sets():
    """Thirteen sets (three blocks of four and a part block) that differ where lanes could part:
    the drives (pump_controlled takes more substeps), cylinder, payload, oil, the controller's
    gains, speed and start, a set too stiff to step at all, and a first set (the block's first
    lane, which the spare and failed lanes follow) whose energy balance breaks mid-run."""
    base = with_updates(Parameters(), command_payload_times_s=[0.6], command_payload_fractions=[0.0])
    params = [with_updates(base, end_stop_stiffness_n_m=1.0, external_rod_force_n=2e5, end_stop_damping_n_s_m2=0.0)]
    params += [
        with_updates(base, piston_diameter_m=d, rod_diameter_m=0.55 * d, payload_mass_kg=m, bulk_modulus_pa=e)
        for d, m, e in [(0.04, 0.0, 1e9), (0.05, 100.0, 1.5e9), (0.07, 250.0, 0.8e9), (0.06, 50.0, 1.2e9)]
    ]
    params += [with_updates(base, drive=d) for d in ("load_sensing", "fixed_pump", "pump_controlled")]
    params.append(with_updates(base, bulk_modulus_pa=1e11, piston_dead_volume_m3=1e-9, initial_length_m=1.05))
    params += [with_updates(params[2], external_rod_force_n=f) for f in (-3000.0, 2000.0)]
    params += [with_updates(base, drive="pump_controlled", payload_mass_kg=300.0)]
    params += [with_updates(base, drive="fixed_pump")]
    own = [  # each set's controller: gains, speed and start
        {"control_position_gain_1_rad": 4.0 + 0.5 * k, "control_max_speed_rad_s": 0.2 + 0.02 * k}
        | ({"initial_length_m": p.initial_length_m + 0.002 * k} if k != 8 else {})
        for k, p in enumerate(params)
    ]
    return [from_mapping(values, base=p) for values, p in zip(own, params)]


@pytest.mark.skipif(not accelerate.available(), reason="numba not installed")
@pytest.mark.parametrize("kind", ["profile", "position loop"])
def test_sets_in_lock_step_on_the_vector_units_give_each_sets_own_run_to_the_bit(kind):
    """From lanes.WIDTH sets on, the compiled batch runs blocks of sets in lock-step (solve/lanes):
    every set's metrics, failure, substeps, last state and stored outputs equal its run alone,
    through a payload put down, each set's own substeps and controller, a set that cannot step
    at all and a block's first set failing mid-run, in slices of a few samples."""
    from boom_hydraulics.solve import lanes, physical_kernel
    from boom_hydraulics.solve.batch import SetRun
    from boom_hydraulics.solve.closed_loop import PositionLoop

    params = _lock_step_sets()

    def command(sets):
        if kind == "profile":
            return commands.steps([0.0, 0.4, 0.9], [1.0, -0.6, 0.3])
        return PositionLoop.of_parameters(sets)

    params = [with_updates(p, command_times_s=[0.1], command_angles_rad=[0.9]) for p in params]
    together = SetRun(params, 1.2, command(params), every=7, store=True, slice_rows=40)
    assert together._runner is physical_kernel.blocks_rk4 and len(params) % lanes.WIDTH != 0  # a part block too
    rows = [[] for _ in params]
    for taken in together.slices():  # slices of at most 40 samples: the kernel called again and again
        for k, n in enumerate(taken):
            rows[k].append(together.rows[k, :n].copy())
    runs = together.result()
    assert runs.failed_why[0] in (outcomes.ENERGY, outcomes.NONFINITE) and 0.1 < runs.failed_at_s[0] < 1.0
    assert runs.failed_why[8] == outcomes.TOO_STIFF and runs.failed_at_s[8] == 0.0
    assert (np.delete(runs.failed_why, [0, 8]) == outcomes.OK).all()
    assert set(runs.most_substeps[1:8]) != {1}  # the lanes took substeps of their own
    for k, p in enumerate(params):
        alone = run_sets([p], 1.2, command([p]), every=7, store=True)
        assert np.array_equal(runs.states[k], alone.states[0], equal_nan=True), k
        assert np.array_equal(np.concatenate(rows[k]), alone.rows[0, : alone.samples[0]], equal_nan=True), k
        for name, values in runs.metrics.items():
            assert np.array_equal(values[k], alone.metrics[name][0], equal_nan=True), (k, name)
        for field in ("failed_at_s", "failed_why", "most_substeps", "samples"):
            assert np.array_equal(getattr(runs, field)[k], getattr(alone, field)[0], equal_nan=True), (k, field)


@pytest.mark.skipif(not accelerate.available(), reason="numba not installed")
def test_exp_of_a_block_is_each_lanes_float_exp_and_of_a_block_of_zeros_one_without_a_call():
    """lanes' exp: each lane's math.exp, to the bit; a block of zeros (+0 or -0: a chamber's
    volume within its stroke) 1.0, which is what exp gives there, without calling it."""
    import numba

    from boom_hydraulics.solve import lanes

    @numba.njit
    def block_exp(values):
        x = lanes.block()
        for j in range(len(values)):
            x = lanes.with_lane(x, j, values[j])
        e = math.exp(x)
        return np.array([lanes.lane(e, j) for j in range(len(values))])

    for values in ([0.0, -0.0, 0.0, -0.0], [0.0, -0.0, -1e-300, 0.0], [-0.3, 2.0, -745.2, 709.7]):
        got = block_exp(np.array(values))
        assert [float(v).hex() for v in got] == [math.exp(v).hex() for v in values], values
