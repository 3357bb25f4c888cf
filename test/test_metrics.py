"""The design metrics of a run (analysis/metrics.py) on signals whose figures are known in closed
form: a ramp that reaches its target fraction exactly at a sample, a command that opens late
(and one that lowers first), a run without a lift, a closed-loop move with a known overshoot."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from boom_hydraulics.analysis import metrics as analysis

LIFT_M = 0.5


def _ramp(delay_samples: int = 3, t0: float = 1.0) -> dict[str, np.ndarray]:
    """A rod rising ``LIFT_M`` at a constant speed from the first opening (sample ``delay_samples``,
    t = t0 + 0.1 s * samples), energies rising with time, a full tank of pressures."""
    n = 21
    t = t0 + 0.1 * np.arange(n)
    u = np.where(np.arange(n) >= delay_samples, 1.0, 0.0)
    moving = np.clip(np.arange(n) - delay_samples, 0, 10) / 10.0  # 0 .. 1 in ten samples
    q1 = 0.2 + LIFT_M * moving
    supply = 2000.3 * (t - t0)
    return {
        "t": t,
        "q1": q1,
        "v": np.gradient(q1, t),
        "u": u,
        "p1": np.full(n, 5.0e6),
        "p2": np.full(n, 1.0e6),
        "supply_energy": supply,
        "valve_loss_energy": 0.25 * supply + 0.01,
    }


def test_time_to_target_counts_from_the_first_opening_and_includes_the_exact_fraction():
    signals = _ramp(delay_samples=3)
    m = analysis.metrics(signals, target_fraction=0.9)
    assert m["lift_m"] == pytest.approx(LIFT_M)
    # 90 % of the lift is reached exactly at the 9th sample after opening: 0.9 s after it.
    assert m["time_to_target_s"] == pytest.approx(0.9, abs=1e-9)
    assert analysis.metrics(signals, target_fraction=0.95)["time_to_target_s"] == pytest.approx(1.0, abs=1e-9)
    assert analysis.metrics(signals, target_fraction=1.0)["time_to_target_s"] == pytest.approx(1.0, abs=1e-9)


def test_duration_and_energy_per_metre_of_a_run_that_does_not_start_at_zero():
    signals = _ramp(t0=1.0)
    m = analysis.metrics(signals)
    assert m["duration_s"] == pytest.approx(2.0)
    supply = signals["supply_energy"][-1]
    assert m["supply_energy_j"] == pytest.approx(supply)
    assert m["supply_energy_per_m_j_m"] == pytest.approx(supply / LIFT_M, rel=1e-12)
    assert m["valve_loss_per_m_j_m"] == pytest.approx((0.25 * supply + 0.01) / LIFT_M, rel=1e-12)


def test_an_opening_command_at_the_first_sample_and_a_lowering_one_before_it():
    at_once = analysis.metrics(_ramp(delay_samples=0))
    assert at_once["time_to_target_s"] == pytest.approx(0.9, abs=1e-9)
    # Lowering first (u < 0) is not the opening: the lift's time counts from the first u > 0.
    lowered = _ramp(delay_samples=3)
    lowered["u"][1] = -0.5
    assert analysis.metrics(lowered)["time_to_target_s"] == pytest.approx(0.9, abs=1e-9)


def test_a_run_without_a_lift_has_no_target_time_nor_energy_per_metre():
    signals = _ramp()
    signals["q1"] = np.full(len(signals["t"]), 0.2)
    m = analysis.metrics(signals)
    assert m["lift_m"] == 0.0
    for name in ("time_to_target_s", "supply_energy_per_m_j_m", "valve_loss_per_m_j_m"):
        assert math.isnan(m[name]), name
    falling = _ramp()
    falling["q1"] = 0.2 - 0.1 * np.arange(len(falling["t"]))  # lowered only: its largest rise is 0
    assert math.isnan(analysis.metrics(falling)["time_to_target_s"])


def test_missing_signals_count_as_zero_and_a_missing_battery_as_unknown():
    m = analysis.streamed({"t": np.array([0.0, 1.0, 2.0]), "p1": np.array([1.0e6, 3.0e6, 2.0e6])})
    assert m["peak_pressure_pa"] == 3.0e6 and m["min_pressure_pa"] == 0.0  # p2 missing: 0 Pa
    assert m["supply_energy_j"] == 0.0 and m["peak_speed_m_s"] == 0.0 and m["cavitation_s"] == 0.0
    for name in ("battery_energy_j", "battery_drawn_j", "lift_work_j", "peak_battery_power_w", "efficiency"):
        assert math.isnan(m[name]), name
    battery = analysis.streamed(
        {
            "t": np.array([0.0, 1.0, 2.0]),
            "battery_drawn": np.array([0.0, 100.0, 300.0]),
            "battery_returned": np.array([0.0, 0.0, 20.0]),
            "lift_work": np.array([0.0, 50.0, 140.0]),
        }
    )
    assert battery["battery_energy_j"] == pytest.approx(280.0)
    assert battery["efficiency"] == pytest.approx(0.5)
    assert battery["peak_battery_power_w"] == pytest.approx(180.0)


def test_lift_metrics_are_the_streamed_ones_for_the_angle_given():
    t = np.arange(0.0, 2.0, 0.1)
    alpha = 0.3 + np.radians(10.0) * t
    signals = {"t": t, "alpha": alpha, "u": np.ones(len(t)), "supply_energy": 1000.0 * t}
    m = analysis.lift_metrics(signals, lift_angle_deg=5.0)
    assert set(m) == {"rise_deg", "lift_completed", "lift_time_s", "lift_energy_j", "lift_valve_loss_j"}
    assert m["lift_completed"] == 1.0 and m["lift_time_s"] == pytest.approx(0.5)
    assert m["lift_energy_j"] == pytest.approx(500.0) and m["lift_valve_loss_j"] == 0.0
    assert analysis.lift_metrics(signals)["lift_completed"] == 0.0  # 19 deg of rise: not the default 20


def _decaying_sine(zeta: float = 0.05, f: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0, 4, 1e-3)
    wd = 2 * math.pi * f
    return t, 2.0e6 + 1.0e4 * np.exp(-zeta * wd / math.sqrt(1 - zeta**2) * t) * np.sin(wd * t)


def test_oscillation_of_a_decaying_pressure_and_its_ripple():
    t, p = _decaying_sine()
    frequency, damping = analysis.oscillation(t, p)  # 10 kPa swings: well beyond the 1 kPa ripple
    assert frequency == pytest.approx(3.0, abs=0.05)
    assert damping == pytest.approx(0.05, rel=0.05)
    frequency, damping = analysis.oscillation(t, p, ripple=5.0e4)  # swings inside the ripple
    assert math.isnan(frequency) and math.isnan(damping)


def _step(overshoot: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """A move from 0.2 rad to 0.7 rad: overshoots by ``overshoot`` of the step at 1 s, settles at 2 s
    (within 2 % of the step there, not of what is left of it at the second sample)."""
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    frac = np.array([0.0, 0.6, 1.0 + overshoot, 1.05, 1.002, 1.0, 1.0])
    return t, 0.2 + 0.5 * frac


def test_step_response_overshoot_is_a_fraction_of_the_step_and_settles_in_band():
    t, alpha = _step(0.1)
    figures = analysis.step_response(t, alpha, target_rad=0.7, start_rad=0.2)
    assert figures["overshoot"] == pytest.approx(0.1)
    assert figures["settling_s"] == pytest.approx(2.0)  # inside 2 % of the step from t = 2 s
    assert figures["final_error_rad"] == pytest.approx(0.0, abs=1e-12)
    short = analysis.step_response(t[:-2], alpha[:-2] - 0.01, target_rad=0.7, start_rad=0.2)
    assert short["final_error_rad"] == pytest.approx(0.7 - (alpha[-3] - 0.01))
    held = analysis.step_response(t, np.full(len(t), 0.7), target_rad=0.7, start_rad=0.7)
    assert held["overshoot"] == 0.0 and held["settling_s"] == 0.0


def test_the_first_move_of_a_closed_loop_scenario():
    p = SimpleNamespace(command_profile="angle", command_times_s=(1.0, 4.0), command_angles_rad=(0.7, 0.2))
    step_t, step_alpha = _step(0.2)
    t = np.concatenate([[0.0, 0.5], 1.0 + step_t, [4.5, 5.0]])
    alpha = np.concatenate([[0.2, 0.2], step_alpha, [0.5, 0.2]])
    m = analysis.move_metrics(p, {"t": t, "alpha": alpha})
    assert m["start_deg"] == pytest.approx(math.degrees(0.2))
    assert m["target_deg"] == pytest.approx(math.degrees(0.7))
    assert m["target_overshoot_deg"] == pytest.approx(math.degrees(0.2 * 0.5))
    assert m["settling_s"] == pytest.approx(2.0)  # the second move (from 4 s) is not this one's
    assert m["target_error_deg"] == pytest.approx(0.0, abs=1e-9)
    late = analysis.move_metrics(p, {"t": t[:2], "alpha": alpha[:2]})  # the run ends before the move
    assert all(math.isnan(v) for v in late.values()) and len(late) == 5
    open_loop = analysis.move_metrics(SimpleNamespace(command_profile="valve"), {"t": t, "alpha": alpha})
    assert all(math.isnan(v) for v in open_loop.values())


def test_metrics_of_a_closed_loop_scenario_follow_its_move():
    p = SimpleNamespace(
        command_profile="angle",
        command_times_s=(0.0,),
        command_angles_rad=(0.7,),
        command_payload_times_s=(),
        command_payload_fractions=(),
    )
    t, alpha = _step(0.1)
    signals = {"t": t, "q1": np.full(len(t), 0.2), "u": np.ones(len(t)), "alpha": alpha}
    m = analysis.metrics(signals, params=p)
    assert m["target_overshoot_deg"] == pytest.approx(math.degrees(0.05))
    assert m["worst_target_error_deg"] == pytest.approx(0.0, abs=1e-9)
    assert math.isnan(analysis.metrics(signals)["target_overshoot_deg"])  # open loop: no move


def test_a_lift_without_an_opening_command_is_timed_from_the_first_sample():
    signals = _ramp(delay_samples=3)
    signals["u"] = np.zeros(len(signals["t"]))  # the rod moved with no command (a recorded bag without one)
    assert analysis.metrics(signals)["time_to_target_s"] == pytest.approx(1.2, abs=1e-9)


def test_a_downward_step_overshoots_below_its_target():
    t, alpha = _step(0.1)
    down = 0.9 - alpha  # from 0.7 rad to 0.2 rad, 0.05 rad below it at 1 s
    figures = analysis.step_response(t, down, target_rad=0.2, start_rad=0.7)
    assert figures["overshoot"] == pytest.approx(0.1)
    assert figures["settling_s"] == pytest.approx(2.0)


def test_the_first_move_starts_at_the_first_sample_of_its_window_and_ends_before_the_next():
    p = SimpleNamespace(command_profile="angle", command_times_s=(1.0, 4.0), command_angles_rad=(0.7, 0.2))
    t = np.array([0.0, 0.45, 1.05, 1.5, 2.5, 3.5, 4.0, 4.5])  # none exactly at the move's start
    alpha = np.array([0.1, 0.15, 0.2, 0.6, 0.7, 0.7, 0.4, 0.2])
    m = analysis.move_metrics(p, {"t": t, "alpha": alpha})
    assert m["start_deg"] == pytest.approx(math.degrees(0.2))  # the sample at 1.05 s
    assert m["target_error_deg"] == pytest.approx(0.0, abs=1e-12)  # 4 s is the next move's
    # sampled before the move and from the next one's start only: nothing of this move
    none = analysis.move_metrics(p, {"t": np.array([0.0, 0.5, 4.0, 4.5]), "alpha": np.array([0.1, 0.1, 0.4, 0.3])})
    assert all(math.isnan(v) for v in none.values())
