"""electro_mechanical: the electro-mechanical actuator (EMA) against closed forms and in the run loop:
it holds on its brake without current, on its motor with the screw's torque, lifts and lowers
with the screw's forward and back-driving efficiency, a self-locking screw holds its load, and
the energy ledger closes (docs/model.md, "Drives")."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from conftest import CONFIG, run_tool
from scipy.optimize import brentq

from boom_hydraulics.analysis.labels import drive_words
from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config, ledger, physical
from boom_hydraulics.model.drives import DRIVES, electro_mechanical, holds_oil
from boom_hydraulics.model.geometry import annulus_area_m2, boom_angle_rad, piston_area_m2, static_rod_force_of
from boom_hydraulics.model.parameters import DRIVE_NAMES, Parameters, describe, from_mapping, with_updates
from boom_hydraulics.solve import commands
from boom_hydraulics.solve.simulation import Simulator

P = with_updates(Parameters(), drive="electro_mechanical")
C = physical.constants(P)
RNG = np.random.default_rng(49)
#: Rod travel per motor radian, l / (2 pi N), m/rad.
R = P.ema_screw_lead_m / (2.0 * math.pi * P.ema_gear_ratio)
EMA_PARAMETERS = [name for name in Parameters.__dataclass_fields__ if name.startswith("ema_")]


def _motor_losses(p: Parameters) -> tuple[float, float]:
    """(k_c, k_s) of the motor's loss model from its rated point (docs/model.md, eq. D6)."""
    rated_loss = p.motor_rated_torque_n_m * p.pump_speed_rad_s * (1.0 / p.motor_efficiency - 1.0)
    copper = p.motor_copper_loss_fraction * rated_loss / p.motor_rated_torque_n_m**2
    return copper, (1.0 - p.motor_copper_loss_fraction) * rated_loss / p.pump_speed_rad_s


def _battery_power(electrical_w: float, p: Parameters) -> float:
    """U I for the inverter's power P_el (eq. D8, D9)."""
    u, r = p.battery_voltage_v, p.battery_resistance_ohm
    return u * 2.0 * electrical_w / (u + math.sqrt(u * u - 4.0 * r * electrical_w))


def _state(q1: float, v: float, f_k: float, w: float, s: float, p1: float = 1e5, p2: float = 1e5) -> list[float]:
    y = list(physical.initial_state(P))
    y[0], y[1], y[2], y[3] = q1, v, p1, p2
    y[physical.DRIVE_STATE : physical.DRIVE_STATE + 3] = [f_k, w, s]
    return y


def _run(seconds: float, **updates: object) -> tuple[dict[str, np.ndarray], list[float], Parameters]:
    """The outputs (every 10 ms) and the last state of a run of the EMA, interpreted (command 0
    unless ``updates`` say otherwise)."""
    p = with_updates(P, **{"command_profile": "constant", "command_value": 0.0, **updates})
    sim = Simulator(p, jit=False)
    out = sim.run(seconds, commands.from_parameters(p), every=10)
    return out, list(sim.y), p


def _supply(y: list[float], u: float, c: physical.Constants = C):
    return physical._terms(y, c, u, math).supply


# --- registration and parameters -----------------------------------------------------


def test_the_ema_is_a_registered_drive_with_its_words_and_sourced_parameters_listed_in_the_shipped_file():
    assert DRIVES["electro_mechanical"] is electro_mechanical and "electro_mechanical" in DRIVE_NAMES
    assert drive_words("electro_mechanical") == "EMA (ball screw)"
    with pytest.raises(ConfigError, match=r"drive 'electro_mechanical' needs physical mode"):
        from_mapping({"drive": "electro_mechanical", "mode": "paper"})
    assert not electro_mechanical.VALVE and not holds_oil("electro_mechanical") and holds_oil("pump_controlled")
    shipped = config.read_values(CONFIG / "default.yaml")
    assert len(EMA_PARAMETERS) == 11
    for name in EMA_PARAMETERS:
        meta = describe(name)
        assert meta["group"] == "plant" and meta["description"].startswith("electro_mechanical: "), name
        assert meta["high"] is not None and meta["low"] is not None and shipped[name] == meta["default"], name
    # the drive's top rod speed is the valve drives' pump flow over the piston area (a fair comparison)
    assert R * P.pump_speed_rad_s == pytest.approx(P.pump_max_flow_m3_s / piston_area_m2(P.piston_diameter_m), rel=0.01)


def test_the_node_takes_the_ema_from_a_params_file(tmp_path):
    """What boom_sim checks at its start: the params file's names and values, and the model."""
    node_parameters = pytest.importorskip("boom_hydraulics.ros.node_parameters")
    values = {**config.read_values(CONFIG / "default.yaml"), "drive": "electro_mechanical"}
    path = tmp_path / "ema.yaml"
    path.write_text(config.dumps(values))
    node_parameters.check_params_file(str(path))
    params = from_mapping(values)
    node_parameters.check_node_model(params)
    assert params.drive == "electro_mechanical" and set(EMA_PARAMETERS) <= set(node_parameters.all_names())


# --- holding, lifting, lowering: closed forms ------------------------------------------


def test_holding_on_the_brake_draws_nothing_and_the_brake_carries_the_screws_load():
    """Command 0: the brake holds the rotor, the motor gives no torque; the boom settles onto the
    screw's compliance (F / k_s) and the friction's bristle, and the battery gives nothing."""
    out, y, p = _run(1.0)
    q1, f_k, w, s = y[0], *y[physical.DRIVE_STATE : physical.DRIVE_STATE + 3]
    assert abs(q1 - p.initial_length_m) < 5e-4 and abs(y[1]) < 1e-5 and abs(w) < 1e-3
    # the static balance: the screw carries the boom (the seals' presliding at most their breakaway force)
    s1, s2 = piston_area_m2(p.piston_diameter_m), annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)
    carried = static_rod_force_of(p, q1) + (p.ambient_pressure_pa - p.tank_pressure_pa) * (s1 - s2)
    assert abs(f_k - carried) <= p.static_friction_n
    torque = f_k * R  # the screw's torque on the rotor, held by the friction and the brake
    supply = _supply(y, 0.0)
    assert supply.torque == 0.0 and abs(supply.rate2) * p.ema_inertia_kg_m2 < 1e-3 * torque
    assert -1.0 < s < 0.0 and p.ema_brake_torque_n_m * abs(s) < torque  # the screw's friction helps the brake
    # the settling's ringing drew some iron loss (k_s |w|, under 0.5 J); the held boom draws nothing
    assert out["battery_drawn"][-1] < 0.5 and out["battery_drawn"][-1] - out["battery_drawn"][50] < 1e-4
    assert out["battery_power"][-1] == pytest.approx(0.0, abs=1e-6)
    assert (out["p1"] == p.tank_pressure_pa).all() and (out["p2"] == p.tank_pressure_pa).all()


@pytest.mark.parametrize("bristle", [1.0, -1.0], ids=["after a lift", "after lowering"])
def test_holding_on_the_motor_takes_the_screws_torque_and_costs_the_copper_loss(bristle):
    """At rest, brake released: the speed controller stands the rotor still with the torque
    F l / (2 pi N eta_f) after a lift (the friction against the motor) and F l eta_b / (2 pi N)
    after lowering (the friction with it), and the battery gives the copper loss k_c T^2."""
    force = 6000.0
    p = with_updates(P, ema_brake_threshold=1e-3)  # the brake released at the small command that holds
    c = physical.constants(p)
    y = _state(1.45, 0.0, force, 0.0, bristle)
    u = brentq(lambda u: _supply(y, u, c).rate2, p.ema_brake_threshold, 1.0, xtol=1e-14)
    eta = 1.0 / p.ema_forward_efficiency if bristle > 0 else p.ema_backdrive_efficiency
    expected = force * p.ema_screw_lead_m * eta / (2.0 * math.pi * p.ema_gear_ratio)
    assert _supply(y, u, c).torque == pytest.approx(expected, rel=1e-9)
    copper, _ = _motor_losses(p)
    terms = physical.ledger(0.0, y, c, u)
    assert terms.battery_power == pytest.approx(_battery_power(copper * expected**2, P), rel=1e-9)


def _steady(u: float, initial_length_m: float) -> tuple[list[float], Parameters]:
    """The last state of a run at the constant command ``u`` from ``initial_length_m`` (1.2 s)."""
    _, y, p = _run(1.2, command_profile="constant", command_value=u, initial_length_m=initial_length_m)
    return y, p


def test_lifting_at_constant_speed_draws_f_v_over_the_screws_and_the_motors_efficiency():
    """Battery power lifting: F v / eta_f through the screw, plus the motor's copper and iron
    loss at T = F l / (2 pi N eta_f) and w = v / r, plus the battery's R I^2 (eq. D5-D9, D32)."""
    y, p = _steady(0.3, 1.37)
    v, w = y[1], y[physical.DRIVE_STATE + 1]
    assert v > 0.1 and w == pytest.approx(0.3 * p.pump_speed_rad_s, rel=0.1)  # the speed controller's droop
    force = _supply(y, 0.3).force
    torque = force * R / p.ema_forward_efficiency
    copper, iron = _motor_losses(p)
    electrical = force * v / p.ema_forward_efficiency + copper * torque**2 + iron * w
    assert physical.ledger(0.0, y, C, 0.3).battery_power == pytest.approx(_battery_power(electrical, p), rel=2e-3)
    assert force * v / (p.ema_forward_efficiency * p.motor_efficiency) < _battery_power(electrical, p)


def test_lowering_regenerates_f_v_eta_b_less_the_losses():
    """Lowering, the load drives the screw (eta_b) and the motor generates: the battery takes back
    F |v| eta_b less the motor's copper and iron loss and the battery's R I^2."""
    y, p = _steady(-0.3, 1.62)
    v, w = y[1], y[physical.DRIVE_STATE + 1]
    assert v < -0.1 and y[physical.DRIVE_STATE + 2] == pytest.approx(-1.0, abs=1e-9)  # sliding back-driven
    force = _supply(y, -0.3).force
    torque = force * R * p.ema_backdrive_efficiency
    copper, iron = _motor_losses(p)
    electrical = force * v * p.ema_backdrive_efficiency + copper * torque**2 + iron * abs(w)
    battery = physical.ledger(0.0, y, C, -0.3).battery_power
    assert battery == pytest.approx(_battery_power(electrical, p), rel=2e-3)
    assert -force * abs(v) * p.ema_backdrive_efficiency < battery < 0.0  # it returns power, less than eta_b F v


def test_a_self_locking_screw_holds_its_load_without_brake_or_torque_where_a_ball_screw_lets_it_fall():
    """No brake, command 0 (no motor torque): a trapezoidal screw with eta_b <= 0 stands after its
    presliding; the ball screw (eta_b = 0.78) is back-driven and the boom falls."""
    out, y, p = _run(0.5, ema_brake_torque_n_m=0.0, ema_backdrive_efficiency=-0.5, ema_forward_efficiency=0.4)
    assert abs(y[0] - p.initial_length_m) < 5e-4 and abs(y[1]) < 1e-5
    # the bristle holds the screw's torque where eta_b = 1 - (1 - eta_b) |s| vanishes (eq. D32)
    assert y[physical.DRIVE_STATE + 2] == pytest.approx(-1.0 / (1.0 - p.ema_backdrive_efficiency), rel=1e-6)
    assert out["battery_drawn"][-1] - out["battery_drawn"][25] < 1e-4
    _, fell, p = _run(0.5, ema_brake_torque_n_m=0.0)
    assert fell[0] < p.initial_length_m - 0.02


def test_against_the_end_stop_the_motor_stalls_at_its_torque_limit():
    """Full command into the upper stop: the motor stands at its torque limit, the screw pushes
    with T_max / r (at rest the bristle is near zero), and the battery gives the copper loss."""
    _, y, p = _run(1.5, command_value=1.0)
    assert y[0] >= p.cylinder_max_length_m and abs(y[1]) < 1e-4
    force = _supply(y, 1.0).force
    assert force == pytest.approx(p.ema_torque_limit_n_m / R, rel=0.02)
    copper, _ = _motor_losses(p)
    torque = _supply(y, 1.0).torque
    x = p.ema_inertia_kg_m2 * p.ema_speed_bandwidth_rad_s * p.pump_speed_rad_s / p.ema_torque_limit_n_m
    assert torque == pytest.approx(p.ema_torque_limit_n_m * x / math.sqrt(1.0 + x * x), rel=1e-6)  # eq. D34
    assert physical.ledger(0.0, y, C, 1.0).battery_power == pytest.approx(
        _battery_power(copper * torque**2, p), rel=1e-3
    )


# --- the energy ledger -------------------------------------------------------------------


def _random_state(rng: np.random.Generator) -> tuple[list[float], float]:
    """A state anywhere the EMA goes (and chamber pressures it does not), and a command near and
    away from the brake's threshold."""
    q1 = rng.uniform(P.cylinder_min_length_m - 2e-3, P.cylinder_max_length_m + 2e-3)
    p1, p2 = rng.choice([1e5, 1e5, rng.uniform(1e4, 2e7)], size=2)
    w = rng.uniform(-1.2, 1.2) * P.pump_speed_rad_s
    y = _state(q1, rng.uniform(-0.5, 0.5), rng.uniform(-3e4, 3e4), w, rng.uniform(-1.0, 1.0), p1, p2)
    u = rng.choice([0.0, rng.uniform(-0.05, 0.05), rng.uniform(-1.0, 1.0)])
    return y, u


def test_the_ledger_closes_at_every_state_and_the_stored_energy_changes_as_its_rate_says():
    for _ in range(300):
        y, u = _random_state(RNG)
        c = physical.constants(with_updates(P, external_rod_force_n=RNG.uniform(-3e4, 3e4)))
        terms = physical.ledger(0.0, y, c, u)
        scale = sum(abs(v) for v in terms)
        assert abs(ledger.residual_w(terms)) <= 1e-9 * scale, (y, u, terms)
        losses = [v for (_, _, kind, _), v in zip(ledger.TERMS, terms, strict=True) if kind == "loss"]
        assert min(losses) >= -1e-9 * scale, (y, u, terms)  # every loss takes, none gives
        rate = physical.derivative(0.0, y, c, u)
        h = 1e-7
        ahead = physical.energy([a + h * b for a, b in zip(y, rate)], c)
        behind = physical.energy([a - h * b for a, b in zip(y, rate)], c)
        assert (ahead - behind) / (2 * h) == pytest.approx(rate[8], rel=1e-4, abs=1e-6 * scale)
        if y[2] == y[3] == P.tank_pressure_pa and P.cylinder_min_length_m < y[0] < P.cylinder_max_length_m:
            assert rate[2] == rate[3] == 0.0  # the housing breathes: its chambers stay at tank pressure


def test_over_a_loader_cycle_the_ema_follows_the_moves_and_the_ledger_balances():
    p = with_updates(P, **commands.scenario("loader", 18.5))
    sim = Simulator(p, jit=False)
    start = list(sim.y)
    out = sim.run(18.5, commands.from_parameters(p), every=10)
    integrals = physical.ledger_integrals(sim.y)
    assert ledger.energies_of(integrals)["imbalance_ratio"] < 0.005
    alpha, ground = np.degrees(out["alpha"]), math.degrees(boom_angle_rad(start[0], p.a_m, p.b_m, p.support_height_m))
    assert alpha.max() == pytest.approx(ground + 25.0, abs=0.5) and alpha[-1] == pytest.approx(ground, abs=0.5)
    assert (out["p1"] == p.tank_pressure_pa).all() and (out["p2"] == p.tank_pressure_pa).all()
    # lowering gives back part of what the lifts raised, less the screw's and motor's losses
    assert 0.2 * integrals["lift_work"] < integrals["battery_returned"] < integrals["lift_work"]
    assert integrals["pump_mechanical_loss"] > 0.0 and integrals["valve_loss"] == integrals["oil_work"] == 0.0


# --- as a user runs it ---------------------------------------------------------------------


def test_boom_sweep_compares_the_ema_with_the_eha_on_the_loader_cycle(tmp_path):
    out = tmp_path / "sweep"
    result = run_tool(
        "boom-sweep", "--config", CONFIG / "default.yaml", "--vary", "drive=pump_controlled,electro_mechanical",
        "--scenario", "loader", "--duration", "19", "--no-plots", "--out", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    with (out / "results.csv").open() as handle:
        rows = {row["drive"]: row for row in csv.DictReader(handle)}
    assert set(rows) == {"pump_controlled", "electro_mechanical"}
    ema = rows["electro_mechanical"]
    assert ema["status"] == "ok" and float(ema["battery_returned_j"]) > 0.0
    assert 0.0 < float(ema["battery_energy_j"]) < float(ema["battery_drawn_j"]) and float(ema["cycles_per_charge"]) > 0


# --- the brake, the torque limit and the stability bound -------------------------------------


@pytest.mark.parametrize(
    ("command", "engaged"),
    [(0.0, 1.0), (0.5, 0.5), (-0.5, 0.5), (0.25, 0.84375), (1.0, 0.0), (-1.0, 0.0), (1.5, 0.0)],
)
def test_the_brake_engages_fully_at_a_zero_command_and_releases_smoothly_up_to_its_threshold(command, engaged):
    """b = 1 - smoothstep(|u| / u_b) (eq. D35): fully on at u = 0, half at u_b / 2 either way,
    off from u_b; the motor's torque fades in as (1 - b)."""
    u = command * P.ema_brake_threshold
    assert electro_mechanical.brake_engagement(u, C) == pytest.approx(engaged, rel=1e-12, abs=1e-15)
    x = C.ema_speed_gain * u * P.pump_speed_rad_s / P.ema_torque_limit_n_m  # at rest: x = K_w u w_max / T_max
    torque = (1.0 - engaged) * P.ema_torque_limit_n_m * x / math.sqrt(1.0 + x * x)
    assert electro_mechanical.motor_torque_n_m(0.0, u, C) == pytest.approx(torque, rel=1e-12, abs=1e-15)


def test_the_motor_is_saturated_exactly_where_its_speed_controller_asks_more_than_the_torque_limit():
    """pump_saturated for the EMA: 1 where K_w |u w_max - w| > T_max (eq. D34), else 0."""
    y = _state(1.4, 0.0, 0.0, 0.0, 0.0)
    edge = P.ema_torque_limit_n_m / (C.ema_speed_gain * P.pump_speed_rad_s)  # the command at the limit from rest
    assert 0.05 < edge < 1.0
    assert _supply(y, 1.0).saturated == 1.0 and _supply(y, -1.0).saturated == 1.0
    assert _supply(y, 0.5 * edge).saturated == 0.0 and _supply(y, -0.5 * edge).saturated == 0.0
    assert _supply(y, 1.01 * edge).saturated == 1.0 and _supply(y, 0.99 * edge).saturated == 0.0
    running = _state(1.4, 0.0, 0.0, 0.5 * P.pump_speed_rad_s, 0.0)  # at the commanded speed: no error
    assert _supply(running, 0.5).saturated == 0.0 and _supply(running, -0.5).saturated == 1.0
    at_limit = P.ema_torque_limit_n_m / C.ema_speed_gain  # 12 rad/s: K_w = 5 N m s, T_max = 60 N m
    assert C.ema_speed_gain * at_limit == P.ema_torque_limit_n_m
    assert _supply(_state(1.4, 0.0, 0.0, -at_limit, 0.0), 0.0).saturated == 0.0  # exactly at the limit: not more
    assert _supply(_state(1.4, 0.0, 0.0, -1.001 * at_limit, 0.0), 0.0).saturated == 1.0


@pytest.mark.parametrize(
    ("force", "speed", "command", "rod_mass"),
    [(0.0, 0.0, 0.0, 1e300), (-2.0e4, -60.0, -0.5, 1e300), (1.5e4, 80.0, 0.3, 270.0)],
    ids=["at rest on the brake", "lowering", "lifting a light boom"],
)
def test_the_stability_bound_adds_the_rates_of_the_speed_loop_the_rotors_springs_and_dampers_and_the_bristle(
    force, speed, command, rod_mass
):
    """The step's fastest rate of the EMA's own states (no line stiffness: the housing only
    breathes): the speed loop's bandwidth w_c = K_w / J, the rotor on the screw's spring k_s r^2
    and on the friction's and brake's presliding stiffness L / theta (L = T_b + r (|m| + |d|) |F_k|),
    the screw's and the bristle's damping, the bristle's relaxation |w| / theta at the speed the
    step may reach, and the screw's spring against the boom's mass at the rod."""
    y = _state(1.4, 0.0, force, speed, 0.3)
    z = physical.drive_states(y)
    level = P.ema_brake_torque_n_m + R * (abs(C.ema_friction_mean) + abs(C.ema_friction_skew)) * abs(force)
    theta, j = electro_mechanical.PRESLIDING_RAD, P.ema_inertia_kg_m2
    spring = math.sqrt((P.ema_screw_stiffness_n_m * R**2 + level / theta) / j)
    damping = (P.ema_screw_damping_n_s_m * R**2 + electro_mechanical.PRESLIDING_DAMPING_S * level / theta) / j
    bristle = (abs(speed) + abs(command) * P.pump_speed_rad_s) / theta
    boom = math.sqrt(P.ema_screw_stiffness_n_m / rod_mass)
    expected = P.ema_speed_bandwidth_rad_s + spring + damping + bristle + boom
    lines_a, lines_b, own = electro_mechanical.stiffness(z, command, 0.0, 1e-3, 1e-3, 1e-3, C, math, rod_mass)
    assert (lines_a, lines_b) == (0.0, 0.0)
    assert own == pytest.approx(expected, rel=1e-12)


def test_the_ema_starts_with_its_screw_unloaded_its_motor_at_rest_and_its_friction_relaxed():
    assert electro_mechanical.initial_state(C) == (0.0, 0.0, 0.0)
    y = physical.initial_state(P)
    assert list(y[physical.DRIVE_STATE : physical.DRIVE_STATE + 3]) == [0.0, 0.0, 0.0]


def test_without_valve_or_pump_the_ema_reports_its_opening_as_x_v_and_the_tank_as_its_supply_pressure():
    """The outputs x_v and p_supply of a drive without a valve and without oil: the opening it
    is handed (the command's lag) and the housing's tank pressure."""
    y = _state(1.4, 0.05, 3e3, 40.0, 0.5)
    y[4] = 0.37
    s = _supply(y, 0.4)
    assert s.spool == 0.37 and s.p_supply == P.tank_pressure_pa and s.cylinder == 1.0
