"""The run kernels' shared code (solve/kernel.py) as Python runs it: the state's layouts, with
and without the model elements' states (an accumulator, hoses, an elastic boom), and a batch
through the kernels' own code (kernel.batch_set: each set from its row of the batch's arrays)
giving each set's interpreted run; and the run loop (kernel.run_set) against what a user sees
of it: the Simulator's own steps, a step's command at its middle, samples at the start, every
n-th step and the end, a run in slices, a payload put down, the controller, failures. The
kernels' Python functions run here, uncompiled (a compiled kernel's ``py_func``), so that these
tests see the same code with numba switched off (tools/mutants runs the model interpreted)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics import jit
from boom_hydraulics.analysis import metrics as analysis
from boom_hydraulics.model import config, physical
from boom_hydraulics.model.geometry import boom_angle_rad
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.model.setpoints import SetpointPath
from boom_hydraulics.solve import accelerate, commands, kernel, outcomes, physical_kernel
from boom_hydraulics.solve.batch import SetRun, SetRuns, run_sets
from boom_hydraulics.solve.closed_loop import PositionLoop
from boom_hydraulics.solve.simulation import OUTPUT_NAMES, Simulator

ACCUMULATOR = with_updates(Parameters(), accumulator_gas_volume_m3=1e-3)
ELASTIC_BOOM = with_updates(Parameters(), boom_bending_stiffness_n_m2=5e6)


def plain(entry: Callable[..., Any] | None) -> Callable[..., Any] | None:
    """A kernel's Python function (a compiled kernel's ``py_func``; with numba off, itself)."""
    return None if entry is None else getattr(entry, "py_func", entry)


@pytest.fixture
def kernels_in_python(monkeypatch: pytest.MonkeyPatch) -> None:
    """A run asked to be compiled runs the run kernel accelerate picks, as Python."""
    monkeypatch.setattr(jit, "available", lambda: True)
    for name in ("batch_runner", "set_runner", "stepper"):
        picked = getattr(accelerate, name)
        monkeypatch.setattr(accelerate, name, lambda *a, picked=picked: plain(picked(*a)))


def test_a_layout_is_as_many_state_components_as_it_names():
    assert kernel.layout(0) == ()
    assert kernel.layout(3) == (0.0, 0.0, 0.0)
    assert len(physical_kernel.BASE) == physical.BASE_SIZE < len(physical_kernel.WHOLE) == len(physical.STATE_NAMES)


def test_a_state_row_round_trips_through_its_layout_and_the_elements_slots_stand():
    row = np.arange(1.0, len(physical.STATE_NAMES) + 1.0)
    before = row.copy()
    base = kernel.state_of(row, physical_kernel.BASE)
    assert base == tuple(row[: physical.BASE_SIZE])  # the state without the elements' states
    assert kernel.state_of(row, physical_kernel.WHOLE) == tuple(row)
    stepped = tuple(-v for v in base)  # the first values moved, as a step of the base layout does
    out = kernel.state_row(row, stepped)
    assert np.array_equal(out[: physical.BASE_SIZE], -before[: physical.BASE_SIZE])
    assert np.array_equal(out[physical.BASE_SIZE :], before[physical.BASE_SIZE :])  # the elements' slots stand
    assert np.array_equal(row, before)  # a copy: the row given stays as it was
    assert np.array_equal(kernel.state_row(row, kernel.state_of(row, physical_kernel.WHOLE)), row)


def _run(params: list[Parameters], duration_s: float, command: Callable, jit_: bool, store: bool = True) -> SetRuns:
    run = SetRun(params, duration_s, command, 10, store=store, jit=jit_)
    assert run.compiled == jit_
    return run.table()


@pytest.mark.usefixtures("kernels_in_python")
@pytest.mark.parametrize(
    "params",
    [
        # explicit Euler at 1 ms breaks its energy balance on the reversal, each set at its own step
        [with_updates(Parameters(), method="euler"), with_updates(Parameters(), payload_mass_kg=150.0, method="euler")],
        [Parameters(), ACCUMULATOR, ELASTIC_BOOM],
    ],
    ids=["euler-failing-without-elements", "rk4-with-elements"],
)
def test_each_set_through_the_batch_kernels_code_is_its_interpreted_run(params):
    command = commands.steps([0.0, 0.1], [1.0, -0.4])
    ours, theirs = _run(params, 0.2, command, True), _run(params, 0.2, command, False)
    ran_through = params[0].method == "rk4"
    assert np.isnan(theirs.failed_at_s).all() == ran_through and (theirs.samples == 21).all() == ran_through
    assert np.array_equal(ours.samples, theirs.samples)
    assert np.array_equal(ours.failed_at_s, theirs.failed_at_s, equal_nan=True)
    assert np.array_equal(ours.failed_why, theirs.failed_why)
    assert np.array_equal(ours.most_substeps, theirs.most_substeps) and ours.reasons == theirs.reasons
    for k in range(len(params)):
        for name in OUTPUT_NAMES:
            assert np.allclose(ours.columns(k)[name], theirs.columns(k)[name], rtol=1e-12, atol=0.0), (k, name)
        assert np.allclose(ours.states[k], theirs.states[k], rtol=1e-12, atol=1e-300), k
    for name, values in ours.metrics.items():
        assert np.allclose(values, theirs.metrics[name], rtol=1e-12, atol=1e-300, equal_nan=True), name


@pytest.mark.usefixtures("kernels_in_python")
def test_a_run_without_elements_leaves_their_slots_of_the_state_as_they_were():
    run = SetRun([Parameters()], 0.05, commands.constant(1.0), 10, jit=True)
    assert not accelerate.with_elements(run.params)
    run.state[0, physical.BASE_SIZE :] = 7.0  # where the base layout would not look
    for _ in run.slices():
        pass
    assert (run.state[0, physical.BASE_SIZE :] == 7.0).all()
    assert run.state[0, 0] != physical.initial_state(Parameters())[0]  # the rod moved


@pytest.mark.usefixtures("kernels_in_python")
def test_a_batch_kernel_that_keeps_no_table_takes_the_same_metrics():
    params = [Parameters(), with_updates(Parameters(), payload_mass_kg=150.0)]
    command = commands.constant(0.8)
    stored = _run(params, 0.1, command, True)
    measured = _run(params, 0.1, command, True, store=False)
    assert measured.rows is None
    for name, values in stored.metrics.items():
        assert np.array_equal(values, measured.metrics[name], equal_nan=True), name
    assert math.isnan(measured.failed_at_s[0]) and np.array_equal(measured.states, stored.states)


# -- the run loop (kernel.run_set), as every interpreted run goes through it


def _stepped_by_hand(p: Parameters, command: Callable[[float], float], steps: int) -> tuple[list, list[float], int]:
    """The Simulator's steps one at a time, each with ``command`` at its middle: the states,
    the commands and the most substeps a step took."""
    sim = Simulator(p, jit=False)
    dt = p.time_step_s
    states, us = [list(sim.y)], []
    for i in range(steps):
        us.append(command((i + 0.5) * dt))
        sim.step(us[-1])
        states.append(list(sim.y))
    return states, us, sim.most_substeps


def test_a_run_is_the_simulators_steps_each_with_the_command_at_its_middle_sampled_every_nth_and_at_the_end():
    p = with_updates(Parameters(), piston_dead_volume_m3=1e-6, bulk_modulus_pa=1e10)  # stiff: 4 substeps a step
    command = commands.steps([0.0, 0.0004, 0.0104, 0.0301], [0.1, 1.0, 0.25, -0.5])  # 0.1 ms before a middle
    states, us, _ = _stepped_by_hand(p, command, 40)
    sim = Simulator(p, jit=False)
    out = sim.run(0.04, command, every=7)
    assert np.allclose(out["t"], [0.0, 0.007, 0.014, 0.021, 0.028, 0.035, 0.04], rtol=0.0, atol=1e-12)
    for row, i in enumerate((0, 7, 14, 21, 28, 35, 40)):  # at the start, every 7th step and at the end
        assert out["q1"][row] == states[i][0] and out["v"][row] == states[i][1], i
        # a sample's command is the next step's: at t = 10 ms the step to 11 ms, whose middle is past 10.4 ms
        assert out["u"][row] == (us[i] if i < 40 else command(0.0405)), i
    assert us[0] == 1.0 and us[9:12] == [1.0, 0.25, 0.25] and us[29:31] == [0.25, -0.5]
    assert sim.t == pytest.approx(0.04) and sim.y == states[40]
    assert sim.u == -0.5  # the command the last step took
    assert out.most_substeps == 4 == sim.most_substeps


def test_a_run_goes_on_from_where_the_last_left_it_on_the_same_time_line():
    p = with_updates(Parameters(), piston_dead_volume_m3=2e-6)
    command = commands.steps([0.0, 0.0154], [1.0, -0.3])
    states, _, _ = _stepped_by_hand(p, command, 30)
    sim = Simulator(p, jit=False)
    sim.run(0.01, command)
    then = sim.run(0.02, command, every=5)  # steps 11 ... 30: the command still at their own middles
    assert np.allclose(then["t"], [0.01, 0.015, 0.02, 0.025, 0.03], rtol=0.0, atol=1e-12)
    assert [list(then["q1"])] == [[states[i][0] for i in (10, 15, 20, 25, 30)]]
    assert sim.y == states[30]


def test_a_run_in_slices_is_the_run_in_one_call_through_a_payload_put_down_and_the_controller():
    p = with_updates(
        Parameters(), command_profile="angle", command_times_s=[0.0], command_angles_rad=[0.75],
        command_payload_times_s=[0.03], command_payload_fractions=[0.0], payload_mass_kg=200.0,
    )  # fmt: skip
    whole = Simulator(p, jit=False).run(0.08, PositionLoop.of_parameters([p]), every=3)
    sim = Simulator(p, jit=False)
    chunks = list(sim.samples(0.08, PositionLoop.of_parameters([p]), every=3, chunk_rows=4))
    assert len(chunks) > 4  # the loop called again and again, each time from where it stopped
    for name in ("t", "q1", "u", "p1", "f_hyd", "battery_drawn"):
        assert np.array_equal(np.concatenate([c[name] for c in chunks]), whole[name]), name
    assert abs(sim.energy_residual()) < 1e-6 * whole["battery_drawn"][-1]  # the payload's change counted once
    released = whole["f_hyd"][whole["t"] > 0.035]
    assert (np.abs(np.diff(whole["u"])) > 0.0).any() and released.size  # the controller moved the valve


def test_a_payload_put_down_at_the_start_runs_as_the_boom_given_no_payload_from_its_held_start():
    p = with_updates(Parameters(), command_payload_times_s=[0.0], command_payload_fractions=[0.0])
    sim = Simulator(p, jit=False)
    out = sim.run(0.03, commands.constant(0.0), every=10)
    by_hand = Simulator(Parameters(), jit=False)  # the boom held with its payload, which then goes
    by_hand.set_payload_mass(0.0)
    q1, start = [by_hand.y[0]], by_hand.outputs()
    for _ in range(3):
        by_hand.step(0.0, 10)
        q1.append(by_hand.y[0])
    assert np.allclose(out["q1"], q1, rtol=1e-9, atol=0.0) and q1[-1] > q1[0] + 1e-4  # the lighter boom rises
    assert out["a"][0] == pytest.approx(start["a"], rel=1e-9) and start["a"] > 1.0  # lighter from the first sample on
    assert abs(sim.energy_residual()) < 1e-3


def test_a_set_that_fails_keeps_its_last_good_state_and_says_when_and_which_command_it_failed_with():
    euler = with_updates(Parameters(), method="euler")
    command = commands.steps([0.0, 0.1], [1.0, -0.4])
    runs = run_sets([euler], 0.2, command, every=1, store=True, jit=False)
    assert runs.failed_why[0] == outcomes.ENERGY
    rows = runs.columns(0)
    failed_step = round(runs.failed_at_s[0] / euler.time_step_s)  # the step that ends at failed_at_s
    assert runs.samples[0] == failed_step  # samples at the start and after each good step
    assert rows["t"][-1] == pytest.approx(runs.failed_at_s[0] - euler.time_step_s)
    assert runs.states[0][0] == rows["q1"][-1]  # the last good state
    states, _, most = _stepped_by_hand(euler, command, failed_step - 1)
    assert list(runs.states[0]) == states[-1]
    assert runs.most_substeps[0] == most == 2  # of the steps taken (the failed one took 1)
    sim = Simulator(euler, jit=False)
    out = sim.run(0.2, command, stop_on_error=True)
    assert out.stopped is not None
    assert sim.u == command((failed_step - 0.5) * euler.time_step_s) == -0.4  # the failed step's command
    assert sim.t == pytest.approx(runs.failed_at_s[0] - euler.time_step_s) and sim.y == states[-1]
    for name in OUTPUT_NAMES:  # the last finite state, added to the samples, as they had it
        assert out[name][-1] == out[name][-2], name


def test_a_set_too_stiff_to_step_stops_at_its_start_with_the_substeps_it_needed_and_the_others_run_on():
    stiff = with_updates(Parameters(), bulk_modulus_pa=1e11, piston_dead_volume_m3=1e-9, initial_length_m=1.05)
    runs = run_sets([stiff, Parameters()], 0.02, commands.constant(1.0), every=5, jit=False)
    assert runs.failed_why[0] == outcomes.TOO_STIFF and runs.failed_at_s[0] == 0.0
    assert runs.most_substeps[0] > outcomes.MAX_SUBSTEPS and runs.samples[0] == 1  # the start alone
    assert runs.failed_why[1] == outcomes.OK and math.isnan(runs.failed_at_s[1]) and runs.samples[1] == 5
    assert runs.most_substeps[1] == 1


def _angle_of(p: Parameters) -> float:
    return boom_angle_rad(p.initial_length_m, p.a_m, p.b_m, p.support_height_m)


def test_the_run_loops_controller_is_the_position_loop_called_step_by_step():
    """The loop's own controller (kernel.controller_value: the knots, gains, integral and
    dead-band kept in the run's status) against the PositionLoop asked as a Python command."""
    p = with_updates(Parameters(), control_integral_gain_1_rad_s=6.0, control_deadband_rad=2e-3)
    a0 = _angle_of(p)
    path = SetpointPath.of([0.0, 0.04, 0.08], [a0, a0 + 0.03, a0 + 0.01], [0.0, 0.4, 0.0])  # cubic segments

    def by_python(t: float, y: Any) -> Any:
        return loop(t, y)

    by_python.feedback = True  # type: ignore[attr-defined]  # a Python function: the kernel cannot take it
    loop = PositionLoop([p], path)
    python_run = Simulator(p, jit=False).run(0.3, by_python, every=5)
    kernel_run = Simulator(p, jit=False).run(0.3, PositionLoop([p], path), every=5)
    for name in ("u", "q1", "alpha"):
        assert np.allclose(kernel_run[name], python_run[name], rtol=1e-9, atol=1e-12), name
    u = kernel_run["u"]
    assert (u > 0.0).any() and (u < 0.0).any() and (u[10:] == 0.0).any()  # up, back, and held within the band


def test_a_payload_stays_whole_on_the_hook_until_the_first_time_its_schedule_gives():
    p = with_updates(Parameters(), command_payload_times_s=[0.02], command_payload_fractions=[0.0])
    scheduled = Simulator(p, jit=False).run(0.03, commands.constant(0.5))
    whole = Simulator(Parameters(), jit=False).run(0.03, commands.constant(0.5))
    before = scheduled["t"] <= 0.02
    for name in ("q1", "f_load", "p1"):
        assert np.array_equal(scheduled[name][before], whole[name][before]), name
    assert scheduled["f_load"][-1] != whole["f_load"][-1]  # put down after


def test_a_step_that_lands_outside_the_geometry_of_eq_1_is_not_taken():
    fig8 = with_updates(config.load(CONFIG / "paper_fig8.yaml"), method="euler")  # one finite stage a step
    runs = run_sets([fig8], 3.0, commands.constant(1.0), every=1, store=True, jit=False)
    assert runs.failed_why[0] == outcomes.OUT_OF_GEOMETRY
    assert 1.7 < runs.last_q1_m[0] < 1.8 and "geometry" in runs.reasons[0]  # the last good state, inside (1, 1.8) m
    assert runs.columns(0)["q1"][-1] == runs.last_q1_m[0]
    assert runs.failed_at_s[0] == pytest.approx(runs.columns(0)["t"][-1] + fig8.time_step_s)  # the failed step's end
    steps = len(runs.columns(0)["t"]) - 1
    states, _, most = _stepped_by_hand(fig8, commands.constant(1.0), steps)
    assert list(runs.states[0]) == states[-1] and runs.most_substeps[0] == most  # of the steps taken


def test_a_set_that_failed_in_an_earlier_slice_takes_no_more_samples_while_the_others_run_on():
    stiff = with_updates(Parameters(), bulk_modulus_pa=1e11, piston_dead_volume_m3=1e-9, initial_length_m=1.05)
    pushed = with_updates(  # driven down onto a soft end stop by 200 kN: its energy balance breaks at 0.141 s
        Parameters(), end_stop_stiffness_n_m=1.0, external_rod_force_n=2e5, end_stop_damping_n_s_m2=0.0
    )
    sets = [stiff, pushed, Parameters()]
    command = commands.steps([0.0, 0.1], [1.0, -0.4])
    whole = run_sets(sets, 0.3, command, every=1, store=True, jit=False)
    assert list(whole.failed_why) == [outcomes.TOO_STIFF, outcomes.ENERGY, outcomes.OK]
    assert list(whole.samples) == [1, 141, 301]
    run = SetRun(sets, 0.3, command, 1, store=True, slice_rows=10, jit=False)
    rows: list[list[np.ndarray]] = [[] for _ in sets]
    for taken in run.slices():  # each slice's samples of each set, as a caller streams them out
        for k, n in enumerate(taken):
            rows[k].append(run.rows[k, :n].copy())
    assert len(rows[2]) > 20  # the loop called again and again
    for k in range(len(sets)):
        assert np.array_equal(np.concatenate(rows[k]), whole.rows[k, : whole.samples[k]]), k
    sliced = run.result()
    assert np.array_equal(sliced.samples, whole.samples) and np.array_equal(sliced.states, whole.states)
    assert np.array_equal(sliced.failed_at_s, whole.failed_at_s, equal_nan=True)


def test_the_metrics_taken_while_running_are_those_of_the_stored_run():
    p = with_updates(Parameters(), payload_mass_kg=120.0)
    runs = run_sets([p], 0.3, commands.steps([0.0, 0.15], [1.0, -0.6]), every=7, store=True, jit=False)
    t = runs.columns(0)["t"]
    assert len(t) == 1 + 300 // 7 + 1 and t[-1] == pytest.approx(0.3)  # step 300 (past 256) sampled too
    expected = analysis.metrics(runs.columns(0), params=p)
    finite = 0
    for name, value in runs.metrics.items():
        both_nan = math.isnan(value[0]) and math.isnan(expected[name])
        assert both_nan or math.isclose(value[0], expected[name], rel_tol=1e-12, abs_tol=1e-15), name
        finite += not both_nan
    assert finite > 5 and runs.metrics["peak_pressure_pa"][0] > p.tank_pressure_pa


def test_a_batch_of_closed_loops_runs_each_set_on_its_own_knots_as_its_single_run():
    params = [
        with_updates(Parameters(), initial_length_m=q, control_position_gain_1_rad=g)
        for q, g in ((1.3, 4.0), (1.45, 7.0))
    ]
    starts = [_angle_of(p) for p in params]
    # each set its own path: from its own start, ending at its own rate; and its own gain
    times, angles, rates = [0.0, 0.03], [starts, [a + 0.02 for a in starts]], [[0.0, 0.0], [0.3, 0.6]]
    batch = run_sets(params, 0.05, PositionLoop(params, SetpointPath.of(times, angles, rates)), every=5,
                     store=True, jit=False)  # fmt: skip
    for k, p in enumerate(params):
        path = SetpointPath.of(times, [a[k] for a in angles], [r[k] for r in rates])
        single = Simulator(p, jit=False).run(0.05, PositionLoop([p], path), every=5)
        for name in ("u", "q1", "alpha"):
            assert np.array_equal(batch.columns(k)[name], single[name]), (k, name)
    assert batch.columns(0)["u"][1] != batch.columns(1)["u"][1]


def test_a_fresh_controller_holds_a_target_within_its_dead_band_and_moves_to_one_past_it():
    p = with_updates(Parameters(), control_deadband_rad=5e-3)
    a0 = _angle_of(p)
    for band_widths, moves in ((0.5, False), (1.5, True)):  # holding starts only once inside the band
        target = SetpointPath.of([0.0], [a0 + band_widths * p.control_deadband_rad])  # there at once
        u = Simulator(p, jit=False).run(0.02, PositionLoop([p], target))["u"]
        assert (u[0] > 0.0) == moves and (u == 0.0).all() != moves, band_widths


def test_a_python_command_is_not_asked_after_the_run_failed():
    euler = with_updates(Parameters(), method="euler")
    asked: list[float] = []

    def command(t: float) -> float:
        asked.append(t)
        return 1.0 if t < 0.1 else -0.4

    sim = Simulator(euler, jit=False)
    out = sim.run(0.5, command, stop_on_error=True)
    assert out.stopped is not None and sim.t < 0.2
    assert max(asked) < sim.t + euler.time_step_s  # the failed step's command at most, none after


def test_a_payload_put_down_and_picked_up_again_is_back_on_the_hook_from_its_time():
    p = with_updates(Parameters(), command_payload_times_s=[0.01, 0.02], command_payload_fractions=[0.0, 1.0])
    out = Simulator(p, jit=False).run(0.03, commands.constant(0.5), every=10)
    by_hand = Simulator(Parameters(), jit=False)
    q1 = [by_hand.y[0]]
    for payload_kg in (0.0, Parameters().payload_mass_kg, None):  # each 10 ms, then the next share
        by_hand.step(0.5, 10)
        q1.append(by_hand.y[0])
        if payload_kg is not None:
            by_hand.set_payload_mass(payload_kg)
    assert np.allclose(out["q1"], q1, rtol=1e-12, atol=0.0)


def test_each_set_of_a_batch_takes_its_metrics_against_its_own_targets():
    """Sets may differ in their closed-loop targets (the metrics' settings), whichever path drives them."""
    base = with_updates(Parameters(), command_profile="angle", command_times_s=[0.0])
    params = [with_updates(base, command_angles_rad=[a]) for a in (0.75, 0.7)]
    runs = run_sets(params, 0.2, PositionLoop.of_parameters(params), every=4, store=True, jit=False)
    for k, p in enumerate(params):
        expected = analysis.metrics(runs.columns(k), params=p)
        for name in ("target_error_deg", "worst_target_error_deg", "target_overshoot_deg"):
            assert math.isclose(runs.metrics[name][k], expected[name], rel_tol=1e-12), (k, name)
    errors = runs.metrics["target_error_deg"]
    assert math.isfinite(errors[0]) and abs(errors[1] - errors[0]) > 1.0  # 0.05 rad (2.9 degrees) apart
