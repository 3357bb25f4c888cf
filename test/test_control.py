"""Closed-loop position control: the controller as a pure function, setpoint paths, and the
step responses and moves a user sees (no ROS graph)."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis.metrics import step_response
from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import physical
from boom_hydraulics.model.control import ControlState, gains_of, position_command
from boom_hydraulics.model.geometry import boom_angle_rad
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.model.setpoints import SetpointPath, move, timed_moves
from boom_hydraulics.solve.batch import run_sets
from boom_hydraulics.solve.closed_loop import PositionLoop
from boom_hydraulics.solve.commands import for_batch
from boom_hydraulics.solve.simulation import Simulator, simulate


def _angle(p: Parameters, q1: float) -> float:
    return boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)


def _step(p: Parameters, step_deg: float, seconds: float = 4.0):
    start = _angle(p, p.initial_length_m)
    target = start + math.radians(step_deg)
    trajectory = Simulator(p).run(seconds, PositionLoop([p], SetpointPath.of([0.0], [target])))
    return trajectory, start, target


def _switches(u: np.ndarray) -> int:
    """How often the valve went from closed to open or back."""
    return int(np.sum(np.diff((u != 0.0).astype(int)) != 0))


@pytest.mark.parametrize("payload_kg", [0.0, 200.0])
@pytest.mark.parametrize(("start_m", "step_deg"), [(1.3, 20.0), (1.6, -20.0)])
def test_a_20_degree_step_settles_within_2_percent_without_a_bounce(payload_kg, start_m, step_deg):
    p = with_updates(Parameters(), payload_mass_kg=payload_kg, initial_length_m=start_m)
    trajectory, start, target = _step(p, step_deg)
    figures = step_response(trajectory["t"], trajectory["alpha"], target, start)
    assert figures["settling_s"] < 3.0
    assert figures["overshoot"] < 0.02  # at most 0.4 degrees past the target
    assert abs(figures["final_error_rad"]) <= 2 * p.control_deadband_rad
    # the valve closes once, at the target, and stays closed: no chatter
    settled = trajectory["t"] > figures["settling_s"] + 0.5
    assert _switches(trajectory["u"][settled]) == 0 and np.all(trajectory["u"][settled] == 0.0)
    assert _switches(trajectory["u"]) <= 3


def test_anti_windup_a_long_saturated_lift_does_not_overshoot():
    """40 degrees from rest: the valve is saturated for most of a second; an integral that wound
    up meanwhile would carry the boom well past the target."""
    p = with_updates(Parameters(), initial_length_m=1.2, control_integral_gain_1_rad_s=5.0)
    trajectory, start, target = _step(p, 40.0, seconds=5.0)
    assert np.sum(trajectory["u"] >= 1.0) > 300  # saturated for 0.3 s and more
    figures = step_response(trajectory["t"], trajectory["alpha"], target, start)
    assert figures["overshoot"] < 0.02 and figures["settling_s"] < 3.0


def test_dead_band_closes_inside_and_opens_again_only_beyond_twice_it():
    p = Parameters()
    c, g = physical.constants(p), gains_of(p)
    q1 = p.initial_length_m
    alpha = _angle(p, q1)
    db = p.control_deadband_rad
    free = ControlState(integral=0.0, holding=0.0)
    u, s = position_command(g, free, q1, c, alpha + 0.5 * db, 0.0, 1e-3)
    assert u == 0.0 and s.holding == 1.0
    u, s = position_command(g, s, q1, c, alpha + 1.5 * db, 0.0, 1e-3)  # inside the hysteresis: still closed
    assert u == 0.0 and s.holding == 1.0
    u, s = position_command(g, s, q1, c, alpha + 2.5 * db, 0.0, 1e-3)
    assert u > 0.0 and s.holding == 0.0
    u, _ = position_command(g, free, q1, c, alpha + 1.5 * db, 0.0, 1e-3)  # not holding: 1.5 db opens
    assert u > 0.0
    u, _ = position_command(g, free, q1, c, alpha + 0.5 * db, 0.1, 1e-3)  # a moving setpoint never holds
    assert u > 0.0
    u, _ = position_command(g, free, q1, c, alpha - 1.0, 0.0, 1e-3)
    assert u == -1.0


def test_the_feedforward_alone_tracks_a_ramp_closely():
    """With Kp ~ 0 and Ki = 0 the feedforward's plant model alone drives the boom at the setpoint's rate."""
    p = with_updates(
        Parameters(), control_position_gain_1_rad=1e-9, control_integral_gain_1_rad_s=0.0, initial_length_m=1.3
    )
    start = _angle(p, p.initial_length_m)
    path = SetpointPath.of([0.0, 2.0], [start, start + 0.4])  # 0.2 rad/s
    trajectory = Simulator(p).run(2.0, PositionLoop([p], path))
    window = (trajectory["t"] > 0.5) & (trajectory["t"] < 2.0)
    rate = np.gradient(trajectory["alpha"], trajectory["t"])[window]
    assert abs(np.mean(rate) - 0.2) < 0.2 * 0.25


def test_setpoint_paths_interpolate_as_joint_trajectory_controller_does():
    linear = SetpointPath.of([1.0, 3.0], [0.0, 1.0])
    assert linear.at(0.0) == (0.0, 0.0)  # before the first knot: hold it
    assert linear.at(2.0) == pytest.approx((0.5, 0.5))
    assert linear.at(5.0) == (1.0, 0.0)
    cubic = SetpointPath.of([0.0, 2.0], [0.0, 1.0], [0.0, 0.0])
    assert cubic.at(1.0) == pytest.approx((0.5, 0.75))  # peak rate 1.5 delta / T
    quintic = SetpointPath.of([0.0, 2.0], [0.0, 1.0], [0.0, 0.0], order=5)
    assert quintic.at(1.0) == pytest.approx((0.5, 0.9375))  # peak rate 1.875 delta / T
    assert cubic.at(0.0)[1] == 0.0 and cubic.at(2.0) == (1.0, 0.0)
    m = move(0.0, 0.1, 0.0, 0.6, 0.25)
    times = np.linspace(0.0, 4.0, 4001)
    rates = np.array([m.at(t)[1] for t in times])
    assert np.max(np.abs(rates)) == pytest.approx(0.25, rel=1e-3)
    assert m.at(float(m.end_s[0])) == (0.6, 0.0)
    # a second move that starts before the first ends takes over from where the setpoint is
    chain = timed_moves(0.0, [0.0, 1.0], [0.6, 0.2], 0.3)
    angle, rate = chain.at(1.0)
    assert 0.0 < angle < 0.6 and rate > 0.0
    assert chain.at(1.0 + 1e-9)[0] == pytest.approx(angle, abs=1e-6)  # continuous
    assert chain.at(30.0) == (0.2, 0.0)


def test_the_angle_scenario_batch_equals_single_runs():
    base = with_updates(
        Parameters(), command_profile="angle", command_times_s=[0.0, 2.0], command_angles_rad=[0.5, 0.3]
    )
    params = [with_updates(base, payload_mass_kg=m, piston_diameter_m=d) for m, d in ((0.0, 0.04), (150.0, 0.05))]
    batch = run_sets(params, 3.0, for_batch(params), every=10, store=True)
    for k, p in enumerate(params):
        single = simulate(p, 3.0, every=10)
        np.testing.assert_allclose(batch.columns(k)["q1"], single["q1"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(batch.columns(k)["u"], single["u"], rtol=0, atol=1e-9)


def test_angle_profile_is_checked():
    with pytest.raises(ConfigError, match="outside the stroke"):
        with_updates(Parameters(), command_profile="angle", command_angles_rad=[1.5])
    with pytest.raises(ConfigError, match="needs mode: physical"):
        with_updates(Parameters(), mode="paper", command_profile="angle", piston_dead_volume_m3=2e-5)
    with pytest.raises(ConfigError, match="equal length"):
        with_updates(Parameters(), command_profile="angle", command_times_s=[0.0, 1.0])


def _boom_sim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "boom_hydraulics.cli.sim", "run", "--config", str(CONFIG / "default.yaml"), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_boom_sim_moves_to_a_target_angle_and_holds(tmp_path):
    out = tmp_path / "move.csv"
    result = _boom_sim("--target-angle-deg", "30", "--duration", "4", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert "closed loop: 8.47 -> 30.00 deg, settled within 2 % in" in result.stdout
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert abs(math.degrees(data["alpha_rad"][-1]) - 30.0) < 0.25
    assert data["u_1"][-1] == 0.0  # holding on the load-holding valve


def test_boom_sim_refuses_a_target_outside_the_stroke_in_one_line(tmp_path):
    result = _boom_sim("--target-angle-deg", "80", "--duration", "1", "--out", str(tmp_path / "x.csv"))
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0 and "outside the stroke" in result.stderr
    assert not (tmp_path / "x.csv").exists()
