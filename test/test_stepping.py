"""Stepping that cannot be silently wrong: the stability bound, the energy guard, ros2, and
the physical elements that keep the default run smooth (Hunt-Crossley stops, cavitation that
conserves oil, the load-holding valve, LuGre friction, ambient pressure).

The reference is scipy's LSODA at rtol 1e-9, integrated piecewise between the command's
steps (the command is held over each piece, as the simulator holds it over each step).
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import CONFIG
from scipy.integrate import solve_ivp

from boom_hydraulics import jit
from boom_hydraulics.errors import SimulationError
from boom_hydraulics.model import end_stops, friction, geometry, physical
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate, integrators, kernel, outcomes, physical_kernel, stepping
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import Simulator

CYCLE = ([0.0, 3.0, 4.0, 7.0], [1.0, 0.0, -1.0, 0.0])  # lift, hold, lower, hold: 9 s
STIFF = {"bulk_modulus_pa": 1.6e9, "piston_dead_volume_m3": 1e-5, "rod_dead_volume_m3": 1e-5}
JIT = accelerate.available()
#: LSODA's absolute tolerance by the kind of each state component (physical.STATE_SCALES).
ATOL = {"length": 1e-10, "velocity": 1e-10, "pressure": 1e-2, "angular_velocity": 1e-8, "unit": 1e-10, "energy": 1e-6}
ATOL["flow"] = 1e-12  # the hoses' flows (model/hoses.py), m^3/s


@jit.kernel(physical_kernel.SOURCES)
def _compiled_rates(t: float, y0: np.ndarray, crow: np.ndarray, u: float) -> np.ndarray:
    """physical.derivative compiled, of the whole state (the layout of physical.initial_state)."""
    return np.array(
        physical.derivative(t, kernel.state_of(y0, physical_kernel.WHOLE), physical_kernel.constants_of(crow), u)
    )


def _rates(p: Parameters):
    """The model's derivative f(t, y, u) for LSODA: compiled where numba is (LSODA calls it some
    10^5 times, a minute of the suite's interpreted), else interpreted; the two are equal to the
    bit (test_accelerate)."""
    c = physical.constants(p)
    if JIT:
        row = np.array(c, dtype=float)
        return lambda t, yy, u: _compiled_rates(t, yy, row, u)
    return lambda t, yy, u: physical.derivative(t, list(yy), c, u)


def reference(p: Parameters, every_s: float = 0.01, duration_s: float = 9.0) -> dict[str, np.ndarray]:
    """The 9 s cycle by LSODA (rtol 1e-9): q1, p1, p2 every ``every_s`` and the supply energy."""
    rates = _rates(p)
    y = physical.initial_state(p)
    atol = [ATOL[scale] for scale in physical.STATE_SCALES]
    ends = [*CYCLE[0][1:], duration_s]
    rows = []
    for start, end, u in zip(CYCLE[0], ends, CYCLE[1]):
        grid = np.arange(round(start / every_s), round(end / every_s) + 1) * every_s
        sol = solve_ivp(
            lambda t, yy, u=u: rates(t, yy, u),
            (start, end),
            y,
            method="LSODA",
            rtol=1e-9,
            atol=atol,
            t_eval=grid,
        )
        assert sol.success, sol.message
        rows.append(sol.y if end == duration_s else sol.y[:, :-1])
        y = sol.y[:, -1]
    ys = np.concatenate(rows, axis=1)
    return {
        "q1": ys[0],
        "p1": np.maximum(ys[2], p.cavitation_pressure_pa),
        "p2": np.maximum(ys[3], p.cavitation_pressure_pa),
        "supply_energy": ys[5],
    }


def cycle(p: Parameters, every_s: float = 0.01) -> tuple[dict[str, np.ndarray], int]:
    """The 9 s cycle by the simulator: outputs every ``every_s`` and the most substeps used."""
    sim = Simulator(p, jit=JIT)
    trajectory = sim.run(9.0, steps(*CYCLE), every=round(every_s / p.time_step_s))
    return trajectory.columns, sim.most_substeps


def test_the_stiff_reproduction_lowers_the_boom_and_says_how_it_stepped(tmp_path):
    """Before: this run exited 0 with q1 ending at 1.746 m and -79.6 kJ drawn from the supply."""
    out = tmp_path / "run.csv"
    result = subprocess.run(
        [sys.executable, "-m", "boom_hydraulics.cli.sim", "run", "--config", str(CONFIG / "default.yaml")]
        + ["--profile", "steps:0=1,3=0,4=-1,7=0", "--duration", "9", "--out", str(out), "--every", "10"]
        + [arg for name, value in STIFF.items() for arg in ("--set", f"{name}={value}")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    assert "substeps per step (stability bound)" in result.stdout
    table = np.genfromtxt(out, delimiter=",", names=True)
    expected = reference(with_updates(Parameters(), **STIFF))
    assert np.max(np.abs(table["q1_m"] - expected["q1"])) < 1e-3
    assert table["q1_m"][-1] < 1.051  # lowered onto the lower stop
    assert table["supply_energy_J"][-1] == pytest.approx(expected["supply_energy"][-1], rel=0.01)


@pytest.mark.parametrize("bulk_modulus_pa", [1e9, 1.6e9, 2e9])
@pytest.mark.parametrize("dead_volume_m3", [1e-6, 1e-5, 1e-4])
def test_stiff_oil_and_short_hoses_match_a_tight_solution(bulk_modulus_pa, dead_volume_m3):
    """Every run matches LSODA within 1 mm on q1 and 1 % on supply energy; a run that cannot
    stops with an error naming the step (pytest would show it as one)."""
    p = with_updates(
        Parameters(),
        bulk_modulus_pa=bulk_modulus_pa,
        piston_dead_volume_m3=dead_volume_m3,
        rod_dead_volume_m3=dead_volume_m3,
    )
    got, most = cycle(p)
    expected = reference(p)
    assert np.max(np.abs(got["q1"] - expected["q1"])) < 1e-3
    assert got["supply_energy"][-1] == pytest.approx(expected["supply_energy"][-1], rel=0.01)
    if dead_volume_m3 <= 1e-5:
        assert most > 5  # the bound, not luck, made it stable


def test_the_default_cycle_converges_across_end_stop_impacts():
    """Both stops are hit; at the default 1 ms the run stays within 1e-5 m and 50 kPa of LSODA
    (measured: 1.1e-6 m and 22 kPa). Against its own run at 1/16 ms: fourth order before the
    first impact (16 times smaller error per halved step); across the impacts, where the
    contact force and the volumes are continuous but their slopes are not, a 4 times
    smaller step still gives an error about 9 times smaller (order 1.6)."""
    p = Parameters()
    got, _ = cycle(p)
    assert got["at_end_stop"].any()
    expected = reference(p)
    assert np.max(np.abs(got["q1"] - expected["q1"])) < 1e-5
    assert max(np.max(np.abs(got[k] - expected[k])) for k in ("p1", "p2")) < 50e3
    fine, _ = cycle(with_updates(p, time_step_s=6.25e-5))
    before_impact = fine["t"] < 1.5
    errors = {}
    for dt in (2e-3, 1e-3, 5e-4):
        run, _ = cycle(with_updates(p, time_step_s=dt))
        deviation = np.abs(run["q1"] - fine["q1"])
        errors[dt] = (np.max(deviation[before_impact]), np.max(deviation))
    assert errors[2e-3][0] / errors[1e-3][0] > 12.0 and errors[1e-3][0] / errors[5e-4][0] > 12.0
    assert errors[2e-3][1] / errors[5e-4][1] > 4.0


def test_without_the_bound_rk4_diverges_and_the_energy_guard_stops_it():
    """The reproduction with the bound switched off (limit 0): the guard, not luck, ends it."""
    p = with_updates(Parameters(), **STIFF)
    c = physical.constants(p)
    y = physical.initial_state(p)
    base = physical.energy(y, c) - y[physical.ENERGY_STATES[0]]
    f = (integrators.rk4_step, physical.derivative, physical.stiffness_rate, physical.energy)
    done, outcome, _, _ = stepping.advance(*f, 0.0, y, c, 1.0, 1e-3, 1, 0.0, 1, 3000, physical.ENERGY_STATES[0], base)
    assert outcome in (stepping.ENERGY, stepping.NONFINITE) and done < 3000


def test_an_unstable_method_is_stopped_with_a_line_that_names_the_step():
    """Euler at 3 substeps: the hydraulic oscillation grows, the balance breaks."""
    sim = Simulator(with_updates(Parameters(), method="euler", substeps=3, spool_time_constant_s=0.0))
    with pytest.raises(SimulationError, match=r"energy balance broken.*step of 0.001 s \(euler") as info:
        sim.run(1.2, steps([0.0, 0.6, 0.9], [1.0, 0.0, -0.5]))
    assert "\n" not in str(info.value)


def test_settings_too_stiff_for_any_substeps_stop_and_point_to_ros2():
    sim = Simulator(with_updates(Parameters(), bulk_modulus_pa=1e11, piston_dead_volume_m3=1e-9, initial_length_m=1.05))
    with pytest.raises(SimulationError, match=r"too stiff.*0.001 s needs \d+ substeps.*method ros2"):
        sim.step(1.0, 10)


@pytest.mark.parametrize("dead_volume_m3", [1e-5, 1e-6])
def test_ros2_takes_the_stiff_reproduction_at_one_step_per_millisecond(dead_volume_m3):
    """L-stable and implicit: no stability substeps; within 0.2 mm and 0.1 % of LSODA, through
    to the end (measured: 0.1 mm, 0.04 %). Where a step's Jacobian does not see what happens
    within it (an end-stop impact; a chamber's void filling, so that its pressure leaves the
    cavitation floor and its stiffness jumps from none to E / V), the step can break the energy
    balance, and is taken again in halves (stepping.advance_halving): with 1 cm³ at the
    impacts, up to 256 substeps (before the halves, that run stopped at the first impact; with
    10 cm³, whether a step held a cavitating chamber against the upper stop through turned on
    LAPACK's rounding, by processor)."""
    p = with_updates(Parameters(), method="ros2", **{**STIFF, "piston_dead_volume_m3": dead_volume_m3,
                                                       "rod_dead_volume_m3": dead_volume_m3})  # fmt: skip
    got, most = cycle(p)
    expected = reference(p)
    assert np.max(np.abs(got["q1"] - expected["q1"])) < 2e-4
    assert got["supply_energy"][-1] == pytest.approx(expected["supply_energy"][-1], rel=1e-3)
    assert got["q1"][-1] < 1.051  # lowered onto the lower stop: the run went to its end
    if dead_volume_m3 < 1e-5:
        assert most > 1  # the halves took it through


def test_ros2_solves_its_stages_as_lapack_does_without_lapack():
    """integrators.lu_factor / lu_solve: LAPACK's solution to rounding, on matrices like a
    stiff step's (I - g h J, the ledger's columns those of I) and on random ones, pivoting
    where the diagonal is small; a singular matrix gives NaN, which the step reports as not
    finite."""
    rng = np.random.default_rng(7)
    for trial in range(20):
        n = 30 if trial % 2 else 5
        a = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1))
        if trial % 2:
            a[:11, 11:], a[11:, 11:] = 0.0, np.eye(n - 11)
        if trial == 3:
            a[0, 0] = 0.0  # a zero on the diagonal: pivoting, not a failure
        b = rng.standard_normal(n)
        factors = a.copy()
        rows = integrators.lu_factor(factors)
        x = integrators.lu_solve(factors, rows, b)
        expected = np.linalg.solve(a, b)
        assert np.max(np.abs(x - expected)) <= 1e-9 * np.max(np.abs(expected))
    for singular in (np.array([[1.0, 2.0], [2.0, 4.0]]), np.array([[2.0, 1.0, 1.0], [4.0, 2.0, 3.0], [2.0, 1.0, 5.0]])):
        rows = integrators.lu_factor(singular)  # the second: its second column's pivot is zero after one step
        assert np.isnan(integrators.lu_solve(singular, rows, np.ones(len(singular)))).all()


def test_a_ros2_step_of_a_model_not_finite_near_its_state_is_not_finite():
    """A Jacobian with inf or NaN gives a step of NaN (not a finite solve of it), which the
    stepping reports as not finite."""
    for bad in (math.inf, math.nan):

        def fun(t, y, bad=bad):
            return [bad * y[0] if y[0] != 1.0 else -y[0], -y[1]]

        assert all(math.isnan(v) for v in integrators.ros2_step(fun, 0.0, [1.0, 1.0], 1e-3))


@pytest.mark.skipif(not JIT, reason="numba not installed")
def test_ros2_solves_its_stages_to_the_same_bits_compiled_and_interpreted():
    """The compiled loops (integrators._lu_factor_compiled, _lu_solve_compiled) do what the
    Python form's row operations do, in the same order: the same factors, row order and
    solution, bit for bit, pivoting and singular matrices included."""
    import numba

    @numba.njit
    def compiled(a, b):
        rows = integrators.lu_factor(a)
        return rows, integrators.lu_solve(a, rows, b)

    rng = np.random.default_rng(3)
    for trial in range(60):
        n = 1 + trial % 30
        a = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1))
        if trial % 5 == 0:
            a[:, 0] = 0.0  # singular
        elif trial % 5 == 1:
            a[0, 0] = 0.0  # pivoting
        b = rng.standard_normal(n)
        python_lu, compiled_lu = a.copy(), a.copy()
        rows = integrators.lu_factor(python_lu)
        x = integrators.lu_solve(python_lu, rows, b)
        compiled_rows, compiled_x = compiled(compiled_lu, b)
        assert np.array_equal(rows, compiled_rows)
        assert np.array_equal(python_lu, compiled_lu, equal_nan=True)
        assert np.array_equal(x, compiled_x, equal_nan=True)


def _toy_step(bad_above_s: float):
    """Explicit Euler that gives NaN for a substep longer than ``bad_above_s``."""

    def step(fun, t, y, h, args):
        return [math.nan] * len(y) if h > bad_above_s else integrators.euler_step(fun, t, y, h, args)

    return step


@pytest.mark.parametrize("bad_above_s, most", [(1.0, 1), (0.6e-3, 2), (0.3e-3, 4)])
def test_a_halving_loop_takes_a_failed_step_again_in_halves_and_equals_advance_where_none_fails(bad_above_s, most):
    f = (_toy_step(bad_above_s), _decay, _rate_of, _stored)  # y' = -y
    done, outcome, used, y = stepping.advance_halving(*f, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 50, -1, 0.0)
    assert (done, outcome, used) == (50, stepping.OK, most)
    assert y[0] == pytest.approx(math.exp(-0.05), rel=1e-3)
    if most == 1:  # nothing failed: advance's run, to the bit
        assert (done, outcome, used, y) == stepping.advance(
            *f, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 50, -1, 0.0
        )


def test_a_halving_loop_stops_where_its_most_substeps_still_fail():
    f = (_toy_step(0.1e-3), _decay, _rate_of, _stored)  # 8 substeps of 0.125 ms: still too long
    done, outcome, most, y = stepping.advance_halving(*f, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 50, -1, 0.0)
    assert (done, outcome, most, y) == (0, stepping.NONFINITE, 8, [1.0])
    f = (_toy_step(0.13e-3), _decay, _rate_of, _stored)  # 8 substeps of 0.125 ms: the last it may try
    assert stepping.advance_halving(*f, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 50, -1, 0.0)[:3] == (
        50,
        stepping.OK,
        8,
    )
    assert stepping.advance_halving(*f, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 4, 50, -1, 0.0)[:3] == (
        0,
        stepping.NONFINITE,
        4,
    )


def test_a_halving_loop_halves_only_the_steps_that_fail_and_goes_on_after_them():
    """Steps fail at one substep only while y > 0.9 (the first 106 steps of y' = -y): those
    take 2, and the rest 1 again, which the result's accuracy shows (Euler at 1 ms, 0.2 s)."""

    def step(fun, t, y, h, args):
        return [math.nan] if y[0] > 0.9 and h > 0.6e-3 else integrators.euler_step(fun, t, y, h, args)

    f = (step, _decay, _rate_of, _stored)
    done, outcome, most, y = stepping.advance_halving(*f, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 200, -1, 0.0)
    assert (done, outcome, most) == (200, stepping.OK, 2)
    halves, whole = 0.9995**2, 0.999
    k = next(i for i in range(200) if halves**i <= 0.9)  # the steps taken in halves, from y > 0.9
    assert y[0] == pytest.approx(halves**k * whole ** (200 - k), rel=1e-12)


def test_a_halving_loop_mends_a_broken_energy_balance_and_not_a_state_that_is_not_finite():
    """y' = -y with y as its stored energy and W its integral: an Euler step of 1 ms balances
    within the tolerance only in halves here; a state already NaN stops at once."""

    def step(fun, t, y, h, args):
        flowed = y[1] + (h * y[0] if h > 0.6e-3 else 0.0)  # a whole step adds energy from nowhere
        return [y[0], flowed, abs(flowed)]

    def stored(y, c):
        return 0.0

    f = (step, _decay, _rate_of, stored)
    done, outcome, most, _ = stepping.advance_halving(*f, 0.0, [1e4, 0.0, 0.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8,
                                                      10, 1, 0.0)  # fmt: skip
    assert (done, outcome, most) == (10, stepping.OK, 2)
    assert stepping.advance(*f, 0.0, [1e4, 0.0, 0.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 10, 1, 0.0)[:2] == (
        0,
        stepping.ENERGY,
    )
    nan_start = stepping.advance_halving(*f, 0.0, [math.nan, 0.0, 0.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 10, 1, 0.0)
    assert nan_start[:3] == (0, stepping.NONFINITE, 1)


def test_only_ros2_halves_its_failed_steps():
    """The explicit methods' substeps come from the stability bound, and their failures end
    the run at once (as the batch kernel's blocks of sets do, which must equal them)."""
    assert {name for name in integrators.METHODS if stepping.loop_of(name) is stepping.advance_halving} == {"ros2"}


def test_ros2_is_l_stable_and_second_order():
    """On y' = lambda y: R(z) -> 0 as z -> -inf, and the error falls 4x per halved step."""
    for z in (-1e3, -1e6):
        assert abs(integrators.ros2_step(lambda t, y, z=z: [z * y[0]], 0.0, [1.0], 1.0)[0]) < 2.0 / abs(z) ** 0.5
    errors = []
    for n in (50, 100):
        y = [1.0]
        for i in range(n):
            y = integrators.ros2_step(lambda t, yy: [-yy[0] + math.sin(t)], i / n, y, 1.0 / n)
        exact = 0.5 * (math.sin(1) - math.cos(1)) + 1.5 * math.exp(-1)
        errors.append(abs(y[0] - exact))
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)


def test_a_cavitating_chamber_keeps_its_oil():
    """The boom moving down at 0.2 m/s with the valve closed: the sealed rod chamber expands and
    cavitates until the oil spring of the piston chamber stops the rod and throws it back up.
    Over the episode, the oil that flowed in equals the chamber's growth minus its void, to
    1e-8 m^3, while the pressure sits at the floor; the void closes before the pressure rises."""
    p = with_updates(Parameters(), initial_velocity_m_s=-0.2, load_holding_valve="none")
    c = physical.constants(p)

    def augmented(t, y, u):  # the model's state plus the integral of the rod chamber's inflow
        return [*physical.derivative(t, y[:-1], c, u), physical.observe(t, y[:-1], c, u)["q_in2"]]

    y, dt = [*physical.initial_state(p), 0.0], 1e-5
    liquid = []  # V2 - V_void - oil in, at every step of the episode: constant if oil is conserved
    for i in range(100000):
        y = integrators.rk4_step(augmented, i * dt, y, dt, (0.0,))
        out = physical.observe(0.0, y[:-1], c, 0.0)
        if out["void2"] > 0.0:
            liquid.append(physical.chamber_volumes(y[0], c)[1] - out["void2"] - y[-1])
            assert out["p2"] == c.p_cav
        elif liquid:
            break  # the void has closed: the pressure rises from here
    assert len(liquid) > 100 and i < 99999
    assert y[1] > 0.0  # thrown back up
    assert max(liquid) - min(liquid) < 1e-8


@pytest.mark.parametrize(("valve", "payload_kg", "rate_mm_s"), [("piston_side", 200.0, 0.005), ("none", 50.0, 0.2)])
def test_a_closed_valve_holds_the_boom_at_the_documented_creep(valve, payload_kg, rate_mm_s):
    """Valve closed for 60 s. With the load-holding valve the boom settles by about 1-2 mm while
    the spool's leakage pressurises the rod chamber, then creeps at 0.0015-0.0024 mm/s (seat
    leakage); without it the spool's leakage lowers it at 0.15 (50 kg) to 0.8 mm/s (200 kg)."""
    sim = Simulator(with_updates(Parameters(), load_holding_valve=valve, payload_mass_kg=payload_kg), jit=JIT)
    sim.step(0.0, 30000)
    settled = sim.y[0]
    sim.step(0.0, 30000)
    creep_mm_s = (settled - sim.y[0]) * 1e3 / 30.0
    assert 0.0 < creep_mm_s < rate_mm_s
    if valve == "none":
        assert creep_mm_s > 0.1  # the spool alone does not hold it


def test_stiction_holds_below_the_breakaway_force_and_slides_above():
    """A 2600 kg rod mass (the boom seen at the rod) on the seals, pushed with a force that
    rises over 1 s to 0.9 or 1.1 times the breakaway force and then stays: below it the rod
    moves a few presliding displacements while the load rises (LuGre's presliding), rings on
    the seals' stiffness and then stands still (no creep)."""
    p = Parameters()
    c = physical.constants(p)
    mass = 2600.0

    def rod(t, y, peak):  # y = [x, v, s]
        decay = friction.stribeck_decay(y[1], c.stribeck)
        ratio = friction.stribeck_level(decay, c.coulomb_ratio, 1.0)
        ds = friction.bristle_rate(y[1], y[2], ratio, c.presliding)
        f = friction.seal_friction_n(y[1], y[2], ds, c.static, c.presliding, c.presliding_damping, decay, c.viscous)
        return [y[1], (peak * min(t, 1.0) - f) / mass, ds]

    for factor in (0.9, 1.1):
        y, h = [0.0, 0.0, 0.0], 1e-3
        for i in range(14000):
            y = integrators.rk4_step(rod, i * h, y, h, (factor * p.static_friction_n,))
        held = y[0]
        for i in range(14000, 15000):
            y = integrators.rk4_step(rod, i * h, y, h, (factor * p.static_friction_n,))
        if factor < 1.0:
            assert abs(y[0]) < 5.0 * p.friction_presliding_m  # presliding, not sliding
            assert abs(y[0] - held) < 1e-7  # its ringing has died away: no creep in the 15th second
        else:
            assert y[1] > 1e-3  # broke away


def test_end_stop_force_starts_from_zero_and_restitution_follows_hunt_crossley():
    """No force jump at first contact, whatever the speed; a free impact on the stop keeps
    e = 1 - 2/3 (lambda / k) v of its speed at low speed, and less the harder it hits."""
    p = Parameters()
    k, lam = p.end_stop_stiffness_n_m, p.end_stop_damping_n_s_m2
    assert end_stops.end_stop_force_n(1.75, 1.0, 1.05, 1.75, k, lam) == 0.0
    assert end_stops.end_stop_force_n(1.75 + 1e-9, 0.0, 1.05, 1.75, k, lam) == pytest.approx(-k * 1e-9)
    assert abs(end_stops.end_stop_force_n(1.75 + 1e-12, 1.0, 1.05, 1.75, k, lam)) < 0.01  # also when fast
    mass = 2600.0

    def restitution(speed: float) -> float:
        y, h = [1.75, speed], 1e-6
        while y[0] >= 1.75 or y[1] > 0.0:
            y = integrators.rk4_step(
                lambda t, yy: [yy[1], end_stops.end_stop_force_n(yy[0], yy[1], 1.05, 1.75, k, lam) / mass], 0.0, y, h
            )
        return -y[1] / speed

    slow = restitution(0.005)
    assert slow == pytest.approx(1.0 - 2.0 / 3.0 * lam / k * 0.005, abs=0.01)
    assert restitution(0.05) < slow


def test_ambient_pressure_pushes_the_rod_in_and_the_start_is_at_rest():
    p = Parameters()
    c = physical.constants(p)
    y = physical.initial_state(p)
    out = physical.observe(0.0, y, c, 0.0)
    assert out["f_hyd"] == pytest.approx(out["p1"] * c.s1 - out["p2"] * c.s2 - p.ambient_pressure_pa * (c.s1 - c.s2))
    assert out["f_hyd"] == pytest.approx(geometry.static_rod_force_of(p, p.initial_length_m), rel=1e-9)
    assert abs(out["a"]) < 1e-9


def test_the_energy_guard_follows_a_payload_change():
    """H changes with the payload, W does not: the balance carries over a change mid-run."""
    sim = Simulator(Parameters())
    sim.step(1.0, 500)
    before = sim.energy_residual()
    sim.set_payload_mass(150.0)
    assert sim.energy_residual() == pytest.approx(before, abs=1e-9)
    sim.step(1.0, 500)
    assert abs(sim.energy_residual()) < 1.0


def _decay(t, y, c, u):
    """A model for the stepping alone: y' = -c[0] y."""
    return (-c[0] * y[0],)


def _rate_of(y, c, u, dt):
    """Its fastest rate: what the test says (c[1]), NaN or huge as it likes."""
    return c[1]


def _stored(y, c):
    """Its stored energy (not checked: energy_index -1)."""
    return 0.0 * y[0]


@pytest.mark.parametrize("rate", [math.nan, math.inf, 1e30], ids=["nan", "inf", "huge"])
def test_a_step_whose_stiffness_has_no_count_of_substeps_stops_as_too_stiff(rate):
    """A rate of NaN, infinity or past any integer count of substeps: the step is not taken and
    says it needs more than the most substeps (it was taken at the least substeps before)."""
    args = (integrators.rk4_step, _decay, _rate_of, None, 0.0, (1.0,), (2.0, rate), 0.0, 1e-3, 1, 2.8, 10_000, 3)
    done, outcome, most, y = stepping.advance(*args, -1, 0.0)
    assert (done, outcome, most, y) == (0, stepping.TOO_STIFF, 10_001, (1.0,))
    steady = stepping.advance(*args[:6], (2.0, 100.0), *args[7:], -1, 0.0)
    assert steady[:3] == (3, stepping.OK, 1) and steady[3][0] == pytest.approx(math.exp(-2.0 * 3e-3))


@pytest.mark.skipif(not accelerate.available(), reason="numba not installed")
def test_a_block_in_lock_step_stops_the_set_whose_stiffness_has_no_count_and_steps_the_others():
    """The same in a block of sets in lock-step (solve/lanes): the set with a rate of NaN is too
    stiff, its state kept; each other set steps with its own substeps, as it would alone."""
    import numba

    from boom_hydraulics.jit import jitable
    from boom_hydraulics.solve import lanes

    decay, rate_of, stored = jitable(_decay), jitable(_rate_of), jitable(_stored)

    @numba.njit
    def block_step(decays, rates):
        template = lanes.block()
        c = lanes.spread((0.0, 0.0), template)
        for j in range(len(rates)):
            c = lanes.with_lane(c, j, (decays[j], rates[j]))
        y = lanes.spread((1.0,), template)
        step = stepping.advance_lanes(
            integrators.rk4_step, decay, rate_of, stored, 0.0, y, c, 0.0 * c[0], 1e-3, 1, 2.8, 10_000, 1, -1, 0.0 * c[0]
        )
        out = np.empty((3, len(rates)))
        for j in range(len(rates)):
            out[0, j], out[1, j], out[2, j] = lanes.lane(step[1], j), lanes.lane(step[2], j), lanes.lane(step[3][0], j)
        return out

    decays, rates = np.array([2.0, 2.0, 3.0, 2.0]), np.array([100.0, math.nan, 8000.0, 2e30])
    out = block_step(decays, rates)  # rates: 1 substep, no count known, 3 substeps, too many
    assert list(out[0]) == [stepping.OK, stepping.TOO_STIFF, stepping.OK, stepping.TOO_STIFF]
    assert list(out[1]) == [1, 10_001, 3, 10_001]
    assert out[2, 1] == out[2, 3] == 1.0  # kept
    for j in (0, 2):  # each as advance takes it alone, to the bit
        c = (float(decays[j]), float(rates[j]))
        alone = stepping.advance(integrators.rk4_step, _decay, _rate_of, None, 0.0, (1.0,), c, 0.0, 1e-3, 1, 2.8,
                                 10_000, 1, -1, 0.0)  # fmt: skip
        assert alone[2] == out[1, j] and alone[3][0] == out[2, j]


def test_what_a_diverged_run_is_told_to_try_fits_its_method():
    """ros2 has tried up to HALVED_MOST substeps itself: it is told a smaller step or rk4, not
    more substeps; rk4 is told more substeps or ros2. The substeps a run reports are named by
    their cause."""
    ros2 = outcomes.step_advice(with_updates(Parameters(), method="ros2"))
    assert f"taken again in up to {stepping.HALVED_MOST} substeps" in ros2 and "method rk4" in ros2
    assert "more substeps" not in ros2
    rk4 = outcomes.step_advice(Parameters())
    assert "more substeps" in rk4 and "method ros2" in rk4
    assert outcomes.substeps_cause("rk4") == "stability bound"
    assert outcomes.substeps_cause("ros2") == "failed steps taken again in halves"


# --- the stepping loop's limits, each exactly at and one past (toy models: fast interpreted) ---


def test_the_energy_balance_holds_exactly_at_its_tolerance_and_breaks_one_past_it():
    """|H - W - (H0 - W0)| may reach ENERGY_TOLERANCE |W| + ENERGY_SLACK_J and no more: with
    W = 300 J (400 J moved either way) and H0 - W0 = 100 J, H = 405 J or 395 J holds, a nJ
    beyond breaks; at rest (W = 0) the slack alone, 1 J, holds."""
    assert (stepping.ENERGY_TOLERANCE, stepping.ENERGY_SLACK_J) == (0.01, 1.0)  # docs/model.md, "Stepping"
    for stored in (405.0, 395.0):
        assert not stepping.balance_broken(stored, 300.0, 400.0, 100.0)
    for stored in (405.0 + 1e-9, 395.0 - 1e-9):
        assert stepping.balance_broken(stored, 300.0, 400.0, 100.0)
    assert not stepping.balance_broken(101.0, 0.0, 0.0, 100.0) and not stepping.balance_broken(99.0, 0.0, 0.0, 100.0)
    assert stepping.balance_broken(101.0 + 1e-9, 0.0, 0.0, 100.0)
    broken = stepping.balance_broken(np.array([405.0, 406.0]), 300.0, 400.0, 100.0)  # sets of a batch alike
    assert list(broken) == [False, True]


def _rk4_substeps(y: float, decay: float, h: float, count: int) -> float:
    for j in range(count):
        y = integrators.rk4_step(_decay, j * h, [y], h, ((decay, 0.0), 0.0))[0]
    return y


def test_a_step_at_its_most_substeps_is_taken_and_one_past_it_is_too_stiff():
    """dt x rate / limit = 4 exactly with at most 4 substeps: the step is taken in 4 substeps;
    a rate a hair higher needs 5 and stops; at least ``min_substeps`` are taken even where
    the bound asks fewer."""
    args = (integrators.rk4_step, _decay, _rate_of, None, 0.0, (1.0,))
    at = stepping.advance(*args, (0.3, 16.0), 0.0, 0.5, 1, 2.0, 4, 2, -1, 0.0)
    assert at[:3] == (2, stepping.OK, 4)
    assert at[3][0] == pytest.approx(_rk4_substeps(_rk4_substeps(1.0, 0.3, 0.125, 4), 0.3, 0.125, 4), rel=1e-15)
    past = stepping.advance(*args, (0.3, 16.000001), 0.0, 0.5, 1, 2.0, 4, 2, -1, 0.0)
    assert past == (0, stepping.TOO_STIFF, 5, (1.0,))
    least = stepping.advance(*args, (0.3, 16.0), 0.0, 0.5, 6, 2.0, 10, 1, -1, 0.0)
    assert least[:3] == (1, stepping.OK, 6) and least[3][0] == pytest.approx(_rk4_substeps(1.0, 0.3, 0.5 / 6, 6))
    assert stepping.advance_halving(*args, (0.3, 16.000001), 0.0, 0.5, 1, 2.0, 4, 2, -1, 0.0) == past


def test_a_too_stiff_step_reports_its_count_below_the_bound_and_more_than_the_most_at_it():
    """A bound just below BEYOND reports the substeps it needs; at BEYOND and past, the most
    substeps + 1 (no count of its own); the halving loop passes the stop on as it is."""
    args = (integrators.rk4_step, _decay, _rate_of, None, 0.0, (1.0,))
    below = stepping.advance(*args, (1.0, 1e17), 0.0, 1.0, 1, 1.0, 100, 3, -1, 0.0)
    assert below == (0, stepping.TOO_STIFF, 10**17, (1.0,))
    at = stepping.advance(*args, (1.0, stepping.BEYOND), 0.0, 1.0, 1, 1.0, 100, 3, -1, 0.0)
    assert at == (0, stepping.TOO_STIFF, 101, (1.0,))
    for rate in (1e17, stepping.BEYOND, math.nan):
        c = (1.0, rate)
        halving = stepping.advance_halving(*args, c, 0.0, 1.0, 1, 1.0, 100, 3, -1, 0.0)
        assert halving == stepping.advance(*args, c, 0.0, 1.0, 1, 1.0, 100, 3, -1, 0.0)


def _clock(t, y, c, u):
    """A model that reads the time: y' = t (rk4 integrates it exactly)."""
    return (t,)


def test_each_step_and_substep_is_taken_at_its_own_time_and_a_retried_one_at_its_steps():
    """y' = t from t0 = 2 s over 4 steps of 0.25 s in 2 substeps each is (3^2 - 2^2) / 2 exactly;
    the halving loop, whose whole steps fail from 2.2 s to 2.6 s, takes them again at their time."""
    args = (_rate_of, _stored, 2.0, [0.0], (0.0, 0.0), 0.0, 0.25)
    done, outcome, most, y = stepping.advance(integrators.rk4_step, _clock, *args, 2, 0.0, 8, 4, -1, 0.0)
    assert (done, outcome, most) == (4, stepping.OK, 2) and y[0] == pytest.approx(2.5, rel=1e-14)

    def step(fun, t, y, h, args):  # a whole step fails at 2.25 s and 2.5 s
        return [math.nan] if h > 0.2 and 2.2 < t < 2.6 else integrators.rk4_step(fun, t, y, h, args)

    done, outcome, most, y = stepping.advance_halving(step, _clock, *args, 1, 0.0, 8, 4, -1, 0.0)
    assert (done, outcome, most) == (4, stepping.OK, 2) and y[0] == pytest.approx(2.5, rel=1e-14)


def test_a_step_that_is_not_finite_stops_the_run_at_the_state_before_it():
    """The third step gives NaN: two steps are taken, and the state is the second's."""

    def step(fun, t, y, h, args):
        return [math.nan] if t >= 2e-3 else integrators.euler_step(fun, t, y, h, args)

    done, outcome, most, y = stepping.advance(step, _decay, _rate_of, _stored, 0.0, [1.0], (1.0, 0.0), 0.0, 1e-3, 1,
                                              0.0, 8, 10, -1, 0.0)  # fmt: skip
    assert (done, outcome, most) == (2, stepping.NONFINITE, 1) and y[0] == pytest.approx(0.999**2, rel=1e-15)


def test_the_energy_check_reads_the_energy_state_wherever_it_is_even_first():
    """energy_index 0 (W first, |W| next): a step that books 10 J from nowhere breaks the balance."""

    def step(fun, t, y, h, args):
        return [y[0] + 10.0, y[1] + 10.0]

    def stored(y, c):
        return 0.0

    f = (step, _decay, _rate_of, stored, 0.0, [0.0, 0.0], (1.0, 0.0), 0.0, 1e-3, 1, 0.0, 8, 5)
    assert stepping.advance(*f, 0, 0.0)[:2] == (0, stepping.ENERGY)
    assert stepping.advance(*f, -1, 0.0)[:2] == (5, stepping.OK)


@pytest.mark.parametrize(("bad_above_s", "outcome"), [(1.0 / 1000, stepping.OK), (1.0 / 2000, stepping.NONFINITE)])
def test_a_halving_loop_takes_a_step_again_in_up_to_halved_most_substeps_and_no_more(bad_above_s, outcome):
    """A step of 1 s that passes only in substeps of 1 ms is taken in HALVED_MOST = 1024 of them;
    one that needs 2048 stops there, whatever ``max_substeps`` allows."""
    assert stepping.HALVED_MOST == 1024
    f = (_toy_step(bad_above_s), _decay, _rate_of, _stored)
    done, got, most, y = stepping.advance_halving(*f, 0.0, [1.0], (1.0, 0.0), 0.0, 1.0, 1, 0.0, 10**6, 1, -1, 0.0)
    assert (done, got, most) == (outcome == stepping.OK, outcome, 1024)
    assert y[0] == (pytest.approx(math.exp(-1.0), rel=1e-3) if outcome == stepping.OK else 1.0)


@pytest.mark.parametrize(
    ("rate", "min_substeps", "step", "energy_index", "expected"),
    [
        (100.0, 1, "rk4", -1, (stepping.OK, 1)),
        (4000.0, 1, "rk4", -1, (stepping.OK, 2)),  # by the bound
        (4000.0, 3, "rk4", -1, (stepping.OK, 3)),  # at least min_substeps
        (10000.0, 1, "rk4", -1, (stepping.OK, 4)),  # exactly at the most substeps
        (10000.1, 1, "rk4", -1, (stepping.TOO_STIFF, 5)),  # one past
        (2.5e20, 1, "rk4", -1, (stepping.TOO_STIFF, 10**17)),  # below BEYOND: the count it needs
        (2.5e21, 1, "rk4", -1, (stepping.TOO_STIFF, 5)),  # at BEYOND: no count of its own, the most + 1
        (1e30, 1, "rk4", -1, (stepping.TOO_STIFF, 5)),
        (100.0, 1, "nan", -1, (stepping.NONFINITE, 1)),  # the state kept
        (100.0, 1, "nan", 1, (stepping.NONFINITE, 1)),  # and not an energy failure
        (100.0, 1, "energy", 1, (stepping.ENERGY, 1)),  # the balance broken: the state kept
        (100.0, 1, "energy", 0, (stepping.ENERGY, 1)),  # W the first state
        (100.0, 2, "energy", -1, (stepping.OK, 2)),  # unchecked
        (100.0, 2, "balanced", 1, (stepping.OK, 2)),  # checked, and within the slack
        (100.0, 1, "moved", 1, (stepping.OK, 1)),  # 1e4 J within 1 % of the 2e6 J moved either way
    ],
)
def test_a_set_stepped_as_a_block_of_one_is_the_step_advance_takes(rate, min_substeps, step, energy_index, expected):
    """advance_lanes on one set (floats, interpreted) takes advance's step: the same outcome,
    substeps (or the substeps it would need) and state, the state kept where the step fails."""

    def kept(fun, t, y, h, args):  # y' = -y, W and |W| staying 0 (H: the constants' c[2])
        return (integrators.rk4_step(fun, t, y[:1], h, args)[0], *y[1:])

    steps = {"rk4": integrators.rk4_step, "nan": _toy_step(0.0), "energy": kept, "balanced": kept, "moved": kept}
    y0 = (1.0,) if step == "rk4" else (1.0, 0.0, 2e6 if step == "moved" else 0.0)

    def stored(y, c):
        return c[2]

    c = (2.0, rate, 1e4 if step in ("energy", "moved") else 0.5)  # 1e4 J from nowhere, or 0.5 J: the slack
    f = (steps[step], _decay, _rate_of, stored, 0.5, y0, c, 0.0, 1e-3, min_substeps, 2.5, 4)
    taken, outcome, most, y = stepping.advance(*f, 1, energy_index, 0.0)
    block = stepping.advance_lanes(*f, 1, energy_index, 0.0)
    assert (outcome, most) == expected and block[0] == 1 and (block[1], block[2]) == (outcome, most)
    assert list(block[3]) == pytest.approx(list(y), rel=1e-15) and taken == (outcome == stepping.OK)
    if step == "rk4" and outcome == stepping.OK:
        assert y[0] == pytest.approx(_rk4_substeps(1.0, 2.0, 1e-3 / most, most), rel=1e-15)


def test_a_block_of_one_steps_its_substeps_at_their_own_times():
    """advance_lanes on y' = t: three substeps of a 0.3 s step from t0 = 2 s integrate it exactly."""
    block = stepping.advance_lanes(integrators.rk4_step, _clock, _rate_of, _stored, 2.0, (0.0,), (0.0, 0.0), 0.0, 0.3,
                                   3, 0.0, 8, 1, -1, 0.0)  # fmt: skip
    assert (block[1], block[2]) == (stepping.OK, 3) and block[3][0] == pytest.approx((2.3**2 - 4.0) / 2, rel=1e-14)


def test_the_outcome_codes_are_distinct_and_zero_is_ok():
    """A sweep's failed_why and the simulator's message read the code: OK is 0 (batch.py) and
    no two outcomes, the geometry's (outcomes.OUT_OF_GEOMETRY) among them, share a code."""
    assert stepping.OK == 0 and outcomes.OUTCOMES["ok"] == 0
    codes = (stepping.OK, stepping.NONFINITE, stepping.ENERGY, stepping.TOO_STIFF, outcomes.OUT_OF_GEOMETRY)
    assert len(set(codes)) == len(codes) and set(codes) == set(outcomes.OUTCOMES.values())


def test_a_halving_loop_goes_on_halving_a_step_whose_balance_stays_broken_and_starts_from_its_least_substeps():
    """A step whose energy balance holds only in substeps of 0.3 ms or less: from 1 substep it
    is taken in 4 (the 2 of the first retry break the balance too); from min_substeps 2, in 4
    and from 3, in 6 (the first retry doubles what failed); the result is Euler's at that step."""

    def step(fun, t, y, h, args):
        flowed = y[1] + (h * y[0] if h > 0.3e-3 else 0.0)  # a substep longer than 0.3 ms books energy from nowhere
        return [y[0] - h * y[0], flowed, abs(flowed)]

    def stored(y, c):
        return 0.0

    for least, most_substeps in ((1, 4), (2, 4), (3, 6)):
        done, outcome, most, y = stepping.advance_halving(step, _decay, _rate_of, stored, 0.0, [1e4, 0.0, 0.0],
                                                          (1.0, 0.0), 0.0, 1e-3, least, 0.0, 64, 3, 1, 0.0)  # fmt: skip
        assert (done, outcome, most) == (3, stepping.OK, most_substeps), least
        h = 1e-3 / most_substeps
        assert y[0] == pytest.approx(1e4 * (1.0 - h) ** (3 * most_substeps), rel=1e-12)


def test_a_halving_loop_passes_a_too_stiff_step_on_even_where_it_may_not_halve():
    """With at most 1 substep (no room to halve), a too stiff step stops as advance stops it."""
    args = (integrators.rk4_step, _decay, _rate_of, None, 0.0, (1.0,), (1.0, 1e4), 0.0, 1e-3, 1, 2.5, 1, 3, -1, 0.0)
    assert stepping.advance_halving(*args) == stepping.advance(*args) == (0, stepping.TOO_STIFF, 4, (1.0,))


def test_a_block_of_one_at_eulers_stability_limit_takes_the_substeps_advance_takes():
    """Euler's limit is 1 (integrators.METHODS): dt x rate = 3 asks 3 substeps, in a block as alone."""
    limit = integrators.METHODS["euler"].stability_limit
    f = (integrators.euler_step, _decay, _rate_of, _stored, 0.0, (1.0,), (2.0, 3000.0), 0.0, 1e-3, 1, limit, 10, 1)
    alone, block = stepping.advance(*f, -1, 0.0), stepping.advance_lanes(*f, -1, 0.0)
    assert alone[1:3] == (block[1], block[2]) == (stepping.OK, 3) and block[3][0] == alone[3][0]
    assert alone[3][0] == pytest.approx((1 - 2e-3 / 3) ** 3, rel=1e-15)
