"""The boom's dynamics seen from the rod (model/mechanics.py, docs/model.md "Mechanics") against
what they must equal: the inertia of a rod about its end plus a point payload, the static rod
force of eq. 6 (no acceleration at rest), the power balance of Lagrange's equation (rod power =
rate of kinetic plus potential energy), and the paper's printed forms (eq. 10, eq. 16 / Fig. 7),
which differ from the corrected ones by exactly the documented factor 1/2 and xi for cos(alpha).
Pure Python and numpy, no simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import geometry, mechanics

TIGHT = 1e-12
A, B, H = 0.4, 1.4, 0.3  # m: pivot to rod eye, pivot to cylinder base, support height
M1, MB, L1, G = 100.0, 250.0, 2.0, 9.81  # boom and payload mass, boom length, gravity
J = M1 * L1 * L1 / 3.0 + MB * L1 * L1
WEIGHT = (0.5 * M1 + MB) * L1 * G  # M_g = WEIGHT cos(alpha)


def test_boom_inertia_is_a_rod_about_its_end_plus_a_point_payload() -> None:
    assert mechanics.boom_inertia_kgm2(300.0, 100.0, 3.0) == pytest.approx(900.0 + 900.0, rel=TIGHT, abs=0.0)
    assert mechanics.boom_inertia_kgm2(100.0, 0.0, 2.0) == pytest.approx(400.0 / 3.0, rel=TIGHT, abs=0.0)
    assert mechanics.boom_inertia_kgm2(M1, MB, L1) == pytest.approx(J, rel=TIGHT, abs=0.0)
    assert mechanics.boom_inertia_kgm2(0.0, 50.0, 2.0) == pytest.approx(200.0, rel=TIGHT, abs=0.0)


def test_effective_mass_is_inertia_times_lever_squared() -> None:
    assert mechanics.effective_mass_kg(1800.0, 0.5) == pytest.approx(450.0, rel=TIGHT, abs=0.0)
    assert mechanics.effective_mass_kg(1800.0, 2.0) == pytest.approx(7200.0, rel=TIGHT, abs=0.0)


def _angle(q1: float) -> float:
    return geometry.boom_angle_rad(q1, A, B, H)


def _numeric(f, q1: float, dq: float = 1e-4) -> tuple[float, float]:
    """(f', f'') at q1 by central differences."""
    return (f(q1 + dq) - f(q1 - dq)) / (2 * dq), (f(q1 + dq) - 2 * f(q1) + f(q1 - dq)) / (dq * dq)


@pytest.mark.parametrize("q1", [1.1, 1.3, 1.6])
def test_at_rest_the_static_rod_force_of_eq_6_holds_the_boom(q1: float) -> None:
    f = geometry.static_rod_force_n(q1, A, B, H, M1, MB, L1, G)
    assert mechanics.rod_acceleration(q1, 0.0, f, J, WEIGHT, A, B, H) == pytest.approx(0.0, abs=1e-9)
    assert mechanics.load_force_n(q1, 0.0, 0.0, J, WEIGHT, A, B, H) == pytest.approx(f, rel=1e-10, abs=0.0)
    # 1 kN more accelerates the boom by 1 kN / (J k^2), its inertia seen at the rod
    k = geometry.lever_rad_per_m(q1, A, B)
    assert mechanics.rod_acceleration(q1, 0.0, f + 1e3, J, WEIGHT, A, B, H) == pytest.approx(
        1e3 / (J * k * k), rel=1e-9
    )


@pytest.mark.parametrize(("q1", "v", "acc"), [(1.1, 0.2, 0.0), (1.3, -0.15, 0.7), (1.6, 0.3, -1.2)])
def test_the_rod_force_is_the_rate_of_the_boom_s_kinetic_and_potential_energy_over_the_rod_speed(
    q1: float, v: float, acc: float
) -> None:
    """Lagrange (eq. 7): F v = d/dt (J alpha'^2 / 2 + WEIGHT sin(alpha)), with alpha(q1) and its
    derivatives taken numerically from the geometry, independently of the lever functions."""
    d1, d2 = _numeric(_angle, q1)
    omega, omega_dot = d1 * v, d2 * v * v + d1 * acc
    power = J * omega * omega_dot + WEIGHT * math.cos(_angle(q1)) * omega
    force = mechanics.load_force_n(q1, v, acc, J, WEIGHT, A, B, H)
    assert force * v == pytest.approx(power, rel=1e-6, abs=0.0)
    # and the acceleration that force gives back is the one it was asked for
    assert mechanics.rod_acceleration(q1, v, force, J, WEIGHT, A, B, H) == pytest.approx(acc, abs=1e-9)


def test_a_coasting_boom_decelerates_by_its_lever_s_slope() -> None:
    # the centripetal term alone: q1'' = -(k'/k) v^2 where the rod force balances the weight
    q1, v = 1.3, 0.4
    f = geometry.static_rod_force_n(q1, A, B, H, M1, MB, L1, G)
    k = geometry.lever_rad_per_m(q1, A, B)
    slope, _ = _numeric(lambda q: geometry.lever_rad_per_m(q, A, B), q1)
    assert mechanics.rod_acceleration(q1, v, f, J, WEIGHT, A, B, H) == pytest.approx(
        -slope / k * v * v, rel=1e-6, abs=0.0
    )


def test_acceleration_at_lever_from_its_parts() -> None:
    # (F - M k) / (J k^2) - (k'/k) v^2 = (5000 - 2000 * 2) / (10 * 4) - (3 / 2) * 0.25
    assert mechanics.acceleration_at_lever(0.5, 5000.0, 10.0, 2000.0, 2.0, 3.0) == pytest.approx(
        25.0 - 0.375, rel=TIGHT
    )


def test_mechanics_run_on_arrays_as_on_floats() -> None:
    q1 = np.array([1.1, 1.3, 1.6])
    v = np.array([0.2, -0.1, 0.0])
    f = mechanics.load_force_n(q1, v, np.array([0.5, 0.0, -1.0]), J, WEIGHT, A, B, H, np)
    acc = mechanics.rod_acceleration(q1, v, f, J, WEIGHT, A, B, H, np)
    assert np.allclose(acc, [0.5, 0.0, -1.0], atol=1e-9)
    assert f[1] == pytest.approx(mechanics.load_force_n(1.3, -0.1, 0.0, J, WEIGHT, A, B, H), rel=TIGHT, abs=0.0)


@pytest.mark.parametrize(("q1", "v", "force"), [(1.1, 0.2, 9e3), (1.3, -0.15, 2e4), (1.6, 0.3, 5e3)])
def test_the_paper_s_acceleration_is_half_the_corrected_one(q1: float, v: float, force: float) -> None:
    """Eq. 16 / Fig. 7 carries a factor 1/2 on the whole right-hand side (module docstring):
    with friction F_f and spring c q1 taken off the piston force, exactly half of q1''."""
    friction, spring = 800.0, 2e3
    paper = mechanics.paper_acceleration(q1, v, force, friction, spring, J, WEIGHT, A, B, H)
    corrected = mechanics.rod_acceleration(q1, v, force - friction - spring * q1, J, WEIGHT, A, B, H)
    assert paper == pytest.approx(0.5 * corrected, rel=1e-10, abs=0.0)
    arrays = mechanics.paper_acceleration(np.array([q1]), v, force, friction, spring, J, WEIGHT, A, B, H, np)
    assert arrays[0] == pytest.approx(paper, rel=TIGHT, abs=0.0)


@pytest.mark.parametrize(("q1", "v", "acc"), [(1.1, 0.2, 0.3), (1.3, -0.15, 0.0), (1.6, 0.3, -1.2)])
def test_eq_10_as_printed_is_the_corrected_force_with_xi_for_cos_alpha(q1: float, v: float, acc: float) -> None:
    printed = mechanics.paper_load_force_n(q1, v, acc, J, M1, MB, L1, G, A, B)
    # with the column's support at the pivot's height (h = 0), cos(alpha) = xi: the two agree
    assert printed == pytest.approx(mechanics.load_force_n(q1, v, acc, J, WEIGHT, A, B, 0.0), rel=1e-10, abs=0.0)
    # elsewhere they differ by the weight term alone: WEIGHT k (xi - cos(alpha))
    k = geometry.lever_rad_per_m(q1, A, B)
    gap = WEIGHT * k * (geometry.xi(q1, A, B) - geometry.cos_boom_angle(q1, A, B, H))
    assert printed - mechanics.load_force_n(q1, v, acc, J, WEIGHT, A, B, H) == pytest.approx(gap, rel=1e-8, abs=0.0)
    arrays = mechanics.paper_load_force_n(np.array([q1]), v, acc, J, M1, MB, L1, G, A, B, np)
    assert arrays[0] == pytest.approx(printed, rel=TIGHT, abs=0.0)


def test_eq_10_weighs_the_payload_fully_and_the_boom_by_half() -> None:
    q1 = 1.3
    k = geometry.lever_rad_per_m(q1, A, B)
    x = geometry.xi(q1, A, B)
    assert mechanics.paper_load_force_n(q1, 0.0, 0.0, J, 0.0, 100.0, L1, G, A, B) == pytest.approx(
        100.0 * G * L1 * x * k, rel=TIGHT
    )
    assert mechanics.paper_load_force_n(q1, 0.0, 0.0, J, 100.0, 0.0, L1, G, A, B) == pytest.approx(
        50.0 * G * L1 * x * k, rel=TIGHT
    )
