"""The electric machine's and inverter's losses, one function for every drive, and the
auxiliary power the machine draws while it is on (docs/model.md, "Electric motor and
inverter", eq. D5-D7).

The defaults are today's two terms, k_c T^2 + k_s |w|, to the bit; each further term (the
inverter's switching with |T|, eddy currents with w^2, windage with |w|^3, the inverter's
standby) is its closed form of the rated point's shares; the rated point keeps the
datasheet's efficiency whatever the shares; and the auxiliary power reaches the battery and
the ledger's standby term, and nothing else, for every drive."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics import jit
from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config, electric_motor, ledger, physical
from boom_hydraulics.model.drives import DRIVES, constants
from boom_hydraulics.model.drives import _nothing as no_supply
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import physical_kernel

P = Parameters()
RNG = np.random.default_rng(49)
#: The shipped overlay of a 48 V PMSM pump motor with its inverter and auxiliaries.
OVERLAY = CONFIG / "motor_pmsm_48v.yaml"
SHARES = ("motor_switching_loss_fraction", "motor_eddy_loss_fraction", "motor_windage_loss_fraction")


def _rated(p: Parameters) -> tuple[float, float, float]:
    """(T_r, w_r, L_r): the rated torque and speed, and the rated loss T_r w_r (1 / eta - 1)."""
    t_r, w_r = p.motor_rated_torque_n_m, p.pump_speed_rad_s
    return t_r, w_r, t_r * w_r * (1.0 / p.motor_efficiency - 1.0)


def _losses(p: Parameters) -> electric_motor.MotorLosses:
    d = constants(p)
    return electric_motor.MotorLosses(
        d.motor_copper, d.motor_iron, d.motor_current, d.motor_eddy, d.motor_windage, d.inverter_standby
    )


def _random_points(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Torques and speeds both ways, to twice the rated ones, with standstill among them."""
    torque = RNG.uniform(-2.0, 2.0, n) * P.motor_rated_torque_n_m
    speed = RNG.uniform(-2.0, 2.0, n) * P.pump_speed_rad_s
    speed[:5] = 0.0
    return torque, speed


def test_the_defaults_are_todays_copper_and_speed_terms_to_the_bit():
    """Every drive's electric chain gives today's P_el = T w + k_c T^2 + k_s |w| + P_sb, with
    k_c and k_s today's split of the rated loss, exactly: today's answers do not move."""
    t_r, w_r, rated_loss = _rated(P)
    k_c = P.motor_copper_loss_fraction * rated_loss / (t_r * t_r)
    k_s = (1.0 - P.motor_copper_loss_fraction) * rated_loss / w_r
    d, m = constants(P), _losses(P)
    assert (d.motor_copper, d.motor_iron) == (k_c, k_s)
    assert (m.current, m.eddy, m.windage, m.standby, d.auxiliary_power) == (0.0, 0.0, 0.0, 0.0, 0.0)
    torque, speed = _random_points(200)
    today = k_c * torque * torque + k_s * np.abs(speed)
    assert np.array_equal(electric_motor.machine_loss_w(torque, speed, m), today)  # on arrays (a batch)
    for t, w in zip(torque[:20], speed[:20], strict=True):
        assert electric_motor.machine_loss_w(float(t), float(w), m) == k_c * t * t + k_s * abs(w)
        s = no_supply(0.0)._replace(torque=float(t), speed=float(w), standby_loss=7.0)
        chain = ledger.electric_chain(s, d)
        assert chain.motor_loss == k_c * t * t + k_s * abs(w)
        assert chain.electrical_power == t * w + (k_c * t * t + k_s * abs(w)) + 7.0
        assert chain.standby_loss == 7.0  # the drive's own standby, nothing added


@pytest.mark.parametrize(
    ("share", "term"),
    [
        ("motor_switching_loss_fraction", lambda t, w, t_r, w_r: abs(t) / t_r),
        ("motor_eddy_loss_fraction", lambda t, w, t_r, w_r: (w / w_r) ** 2),
        ("motor_windage_loss_fraction", lambda t, w, t_r, w_r: abs(w / w_r) ** 3),
    ],
)
def test_each_further_term_is_its_share_of_the_rated_loss_scaled_by_its_closed_form(share, term):
    """A share f of the rated loss L_r taken by a term of |T|, w^2 or |w|^3 gives f L_r times
    (|T| / T_r, (w / w_r)^2, |w / w_r|^3), and leaves the hysteresis and friction term
    (1 - f_c - f) L_r |w| / w_r; the same whichever way the power flows."""
    p = with_updates(P, **{share: 0.15})
    t_r, w_r, rated_loss = _rated(p)
    m = _losses(p)
    f_c = p.motor_copper_loss_fraction
    for t, w in [(0.7 * t_r, 1.3 * w_r), (-1.8 * t_r, 0.4 * w_r), (25.0, -60.0), (40.0, 0.0), (0.0, 250.0)]:
        expected = rated_loss * (f_c * (t / t_r) ** 2 + (1.0 - f_c - 0.15) * abs(w) / w_r + 0.15 * term(t, w, t_r, w_r))
        assert electric_motor.machine_loss_w(t, w, m) == pytest.approx(expected, rel=1e-12)
        assert electric_motor.machine_loss_w(-t, -w, m) == electric_motor.machine_loss_w(t, w, m)


def test_the_inverter_standby_is_drawn_at_standstill_and_booked_as_standby_not_motor_loss():
    """P_0 is a constant while the inverter is enabled: at standstill without torque the chain
    draws P_0, the ledger books it as standby_loss, and the motor loss there is zero."""
    p = with_updates(P, inverter_standby_power_w=25.0, battery_resistance_ohm=0.0)
    d = constants(p)
    chain = ledger.electric_chain(no_supply(0.0), d)
    assert (chain.motor_loss, chain.standby_loss) == (0.0, 25.0)
    assert chain.electrical_power == chain.battery_power == 25.0
    _, w_r, rated_loss = _rated(p)
    m = _losses(p)  # the standby comes out of the speed term, the rated loss stays L_r
    assert m.iron * w_r == pytest.approx((1.0 - p.motor_copper_loss_fraction) * rated_loss - 25.0, rel=1e-12)


@pytest.mark.parametrize("path", [None, OVERLAY], ids=["default", "motor_pmsm_48v"])
def test_the_rated_point_has_the_datasheets_efficiency_both_ways_whatever_the_shares(path):
    """At T_r and w_r: T w / P_el = eta motoring and P_el / (T w) = 2 - 1/eta generating (eq. D7),
    the standby P_0 included; below the rated torque the fixed losses lower it."""
    p = P if path is None else config.load(path)
    t_r, w_r, _ = _rated(p)
    m = _losses(p)
    eta = p.motor_efficiency
    assert electric_motor.efficiency(t_r, w_r, m) == pytest.approx(eta, rel=1e-12)
    assert electric_motor.efficiency(-t_r, w_r, m) == pytest.approx(2.0 - 1.0 / eta, rel=1e-12)
    assert electric_motor.input_power_w(t_r, w_r, m) == pytest.approx(t_r * w_r / eta, rel=1e-12)
    assert electric_motor.efficiency(0.2 * t_r, w_r, m) < eta


def test_the_shipped_48v_overlay_sets_every_term_and_leaves_the_rest_at_the_defaults():
    p = config.load(OVERLAY)
    changed = {k for k in Parameters.__dataclass_fields__ if getattr(p, k) != getattr(P, k)}
    assert changed == {*SHARES, "motor_copper_loss_fraction", "inverter_standby_power_w", "auxiliary_power_w"}
    m = _losses(p)
    assert min(m) > 0.0  # every term on, the hysteresis and friction share left positive


def test_shares_beyond_the_rated_loss_are_refused_in_one_line():
    with pytest.raises(ConfigError, match="exceed the rated loss") as refused:
        with_updates(P, motor_eddy_loss_fraction=0.3, motor_windage_loss_fraction=0.2)
    assert "\n" not in str(refused.value)
    _, _, rated_loss = _rated(P)
    with pytest.raises(ConfigError, match="inverter_standby_power_w"):
        with_updates(P, inverter_standby_power_w=0.5 * rated_loss)  # with the copper share's 0.6
    with_updates(P, inverter_standby_power_w=0.39 * rated_loss)  # within it


def _run(params: Parameters, scenario: str, duration_s: float) -> tuple[dict[str, float], float]:
    """The ledger's energies (J) of a run of ``scenario``, and the simulated time."""
    from boom_hydraulics.solve import commands
    from boom_hydraulics.solve.simulator import Simulator

    params = with_updates(params, **commands.scenario(scenario, duration_s))
    sim = Simulator(params)
    sim.run(duration_s, commands.from_parameters(params), every=500)
    integrals = physical.ledger_integrals(sim.y)
    return ledger.energies_of(integrals), sim.t


def _at_rest(drive: str, auxiliary_w: float, duration_s: float) -> tuple[dict[str, float], float]:
    """The ledger's energies (J) of ``duration_s`` with the valve (or the EHA's command) at 0,
    without the battery's resistance, so that the battery's energy is the terminals'; and the
    simulated time."""
    params = with_updates(P, drive=drive, auxiliary_power_w=auxiliary_w, battery_resistance_ohm=0.0)
    return _run(params, "constant:0", duration_s)


@pytest.mark.parametrize("drive", list(DRIVES))
def test_the_auxiliary_power_adds_its_energy_to_the_battery_and_the_standby_term_and_the_ledger_closes(drive):
    """Over 2 s at rest, P_aux = 40 W draws exactly 80 J more from the battery, booked as
    standby_loss; every other term stays as it was, and the ledger closes."""
    aux_w, duration_s = 40.0, 2.0
    without, t0 = _at_rest(drive, 0.0, duration_s)
    with_aux, t1 = _at_rest(drive, aux_w, duration_s)
    assert t0 == t1 == pytest.approx(duration_s)
    extra = aux_w * t1
    battery = (with_aux["battery_drawn"] - with_aux["battery_returned"]) - (
        without["battery_drawn"] - without["battery_returned"]
    )
    assert battery == pytest.approx(extra, rel=1e-9)
    assert with_aux["standby_loss"] - without["standby_loss"] == pytest.approx(extra, rel=1e-9)
    for name in ledger.TERM_NAMES:
        if name not in ("battery_power", "standby_loss"):
            assert with_aux[name] == pytest.approx(without[name], rel=1e-9, abs=1e-9), name
    assert with_aux["imbalance_ratio"] < 0.005, with_aux


@pytest.mark.parametrize("drive", list(DRIVES))
def test_with_every_loss_term_on_a_lift_and_lower_balances_and_books_both_standbys(drive):
    """The 48 V overlay over make run's cycle (lift, hold, lower, hold): the ledger closes, the
    standby term holds at least the inverter's and the auxiliaries' draw over the run, and the
    motor loss is that of the overlay, not of the defaults."""
    overlay = with_updates(config.load(OVERLAY), drive=drive)
    energies, t = _run(overlay, "cycle", 9.0)
    assert energies["imbalance_ratio"] < 0.005, energies
    fixed = overlay.inverter_standby_power_w + overlay.auxiliary_power_w
    assert energies["standby_loss"] >= fixed * t * (1.0 - 1e-9)
    defaults, _ = _run(with_updates(P, drive=drive), "cycle", 9.0)
    assert energies["motor_loss"] != pytest.approx(defaults["motor_loss"], rel=1e-3)


numba = pytest.importorskip("numba")


@jit.kernel(physical_kernel.SOURCES)  # (cached beside the model's kernels: compiled once, not every run)
def _compiled_chain(s, d):
    return ledger.electric_chain(s, d)


@pytest.mark.skipif(not jit.available(), reason="numba is switched off")
def test_the_electric_chain_with_every_term_compiles_to_the_values_it_gives_interpreted():
    d = constants(config.load(OVERLAY))
    for t, w in [(45.0, 150.0), (-30.0, 120.0), (10.0, 0.0), (0.0, -80.0)]:
        s = no_supply(0.0)._replace(torque=t, speed=w, standby_loss=3.0)
        assert list(_compiled_chain(s, d)) == pytest.approx(list(ledger.electric_chain(s, d)), rel=1e-12, abs=1e-12)
