"""Geometry and statics (eq. 1-6) against hand calculations and identities."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import geometry
from boom_hydraulics.model.parameters import Parameters

P = Parameters()
A, B, H = P.a_m, P.b_m, P.support_height_m
Q = np.linspace(1.02, 1.78, 77)


def test_boom_angle_at_the_paper_start_position():
    # q1 = 1.37 m: xi = 0.21705, theta = 77.464 deg, alpha2 = arccos(1.307/1.4) = 21.001 deg
    alpha = geometry.boom_angle_rad(1.37, A, B, H)
    assert math.degrees(alpha) == pytest.approx(77.464 - 90 + 21.001, abs=0.002)


def test_cos_boom_angle_without_arccos_equals_cos_of_eq_4():
    alpha = geometry.boom_angle_rad(Q, A, B, H, np)
    assert np.allclose(geometry.cos_boom_angle(Q, A, B, H, np), np.cos(alpha), rtol=0, atol=1e-14)


def test_sin_boom_angle_without_arccos_equals_sin_of_eq_4():
    """The stored energy's potential term takes sin(alpha) without arccos; the boom's angles
    here run from below to above the horizontal, so both signs are checked."""
    alpha = geometry.boom_angle_rad(Q, A, B, H, np)
    assert alpha.min() < 0.0 < alpha.max()
    assert np.allclose(geometry.sin_boom_angle(Q, A, B, H, np), np.sin(alpha), rtol=0, atol=1e-14)


def test_lever_is_the_derivative_of_the_boom_angle_and_one_over_a_sin_phi():
    k = geometry.lever_rad_per_m(Q, A, B, np)
    dq = 1e-6
    numeric = (geometry.boom_angle_rad(Q + dq, A, B, H, np) - geometry.boom_angle_rad(Q - dq, A, B, H, np)) / (2 * dq)
    assert np.allclose(k, numeric, rtol=1e-7)
    assert np.allclose(k, 1.0 / (A * np.sin(geometry.rod_boom_angle_rad(Q, A, B, np))), rtol=1e-12)
    dk = (geometry.lever_rad_per_m(Q + dq, A, B, np) - geometry.lever_rad_per_m(Q - dq, A, B, np)) / (2 * dq)
    assert np.allclose(geometry.lever_derivative(Q, A, B, np), dk, rtol=1e-6)


def test_static_force_balances_the_weight_moment_by_virtual_work():
    """F dq1 = M_g d(alpha): eq. 6 written with a sin(phi)."""
    force = geometry.static_rod_force_n(Q, A, B, H, 100.0, 50.0, 2.0, 9.81, np)
    alpha = geometry.boom_angle_rad(Q, A, B, H, np)
    phi = geometry.rod_boom_angle_rad(Q, A, B, np)
    eq6 = (100.0 * 9.81 * 1.0 * np.cos(alpha) + 50.0 * 9.81 * 2.0 * np.cos(alpha)) / (A * np.sin(phi))
    assert np.allclose(force, eq6, rtol=1e-12)
    assert geometry.static_rod_force_n(1.37, A, B, H, 100.0, 50.0, 2.0, 9.81) == pytest.approx(4863, rel=1e-3)


def test_force_grows_without_bound_towards_the_degenerate_triangle():
    # sin(phi) ~ sqrt(q1 - 1): the force grows like 1 / sqrt(q1 - 1), ~3.16x per decade
    near = [geometry.static_rod_force_n(q, A, B, H, 100.0, 50.0, 2.0, 9.81) for q in (1.001, 1.0001)]
    assert abs(near[1]) > 2.5 * abs(near[0]) > 5e4


def test_holding_pressure_scales_with_the_inverse_square_of_the_diameter():
    force = 4863.0
    p40 = geometry.holding_pressure_pa(force, 0.04)
    assert p40 == pytest.approx(force / (math.pi * 0.04**2 / 4))
    assert geometry.holding_pressure_pa(force, 0.08) == pytest.approx(p40 / 4)
    with_rod_side = geometry.holding_pressure_pa(force, 0.04, rod_side_pressure_pa=1e5, rod_diameter_m=0.022)
    assert with_rod_side == pytest.approx(p40 + 1e5 * (0.04**2 - 0.022**2) / 0.04**2)


def test_the_triangle_exists_strictly_between_its_degenerate_lengths():
    """Boundary values of eq. 1: at |b - a| and a + b the triangle is flat (refused), a hair
    inside it exists; the bounds are those lengths whichever of a and b is longer."""
    low, high = geometry.triangle_bounds_m(A, B)
    assert (low, high) == (pytest.approx(B - A, rel=1e-15), pytest.approx(A + B, rel=1e-15))
    assert geometry.triangle_bounds_m(B, A) == (low, high)
    assert not geometry.within_triangle(low, A, B) and not geometry.within_triangle(high, A, B)
    assert geometry.within_triangle(low + 1e-9, A, B) and geometry.within_triangle(high - 1e-9, A, B)
    assert not geometry.within_triangle(high + 1e-9, A, B) and not geometry.within_triangle(low - 1e-9, A, B)
    # the law of cosines: xi is +1 at the short end (theta = 0) and -1 at the long end (theta = pi)
    assert geometry.xi(low, A, B) == pytest.approx(1.0, rel=1e-12)
    assert geometry.xi(high, A, B) == pytest.approx(-1.0, rel=1e-12)
    assert geometry.xi(1.37, A, B) == pytest.approx((A**2 + B**2 - 1.37**2) / (2 * A * B), rel=1e-15)


def test_the_weight_moment_and_the_areas_follow_their_definitions():
    """M_g = (m1 / 2 + mb) L1 g cos(alpha) (eq. 6, 9); S1 = pi D^2 / 4, S2 = pi (D^2 - d^2) / 4."""
    assert geometry.gravity_moment_nm(0.3, 100.0, 50.0, 2.0, 9.81) == pytest.approx(
        (50.0 + 50.0) * 2.0 * 9.81 * math.cos(0.3), rel=1e-15
    )
    assert geometry.gravity_moment_nm(0.3, 140.0, 0.0, 2.5, 9.81) == pytest.approx(
        70.0 * 2.5 * 9.81 * math.cos(0.3), rel=1e-15
    )
    assert geometry.gravity_moment_nm(np.array([0.3]), 140.0, 0.0, 2.5, 9.81, np)[0] == pytest.approx(
        70.0 * 2.5 * 9.81 * math.cos(0.3), rel=1e-15
    )
    assert geometry.piston_area_m2(0.063) == pytest.approx(math.pi * 0.063**2 / 4.0, rel=1e-15)
    assert geometry.annulus_area_m2(0.063, 0.036) == pytest.approx(math.pi * (0.063**2 - 0.036**2) / 4.0, rel=1e-15)
    assert geometry.static_rod_force_of(P, 1.37) == geometry.static_rod_force_n(
        1.37, A, B, H, P.boom_mass_kg, P.payload_mass_kg, P.boom_length_m, P.gravity_m_s2
    )


def test_a_target_exactly_at_an_end_of_the_stroke_is_reachable_and_one_past_it_is_not():
    low, high = geometry.stroke_angles_rad(P)
    assert low == geometry.boom_angle_rad(P.cylinder_min_length_m, A, B, H)
    assert high == geometry.boom_angle_rad(P.cylinder_max_length_m, A, B, H)
    assert low < high
    for angle in (low, high, 0.5 * (low + high)):
        assert geometry.outside_stroke(P, angle) is None
    for angle in (low - 1e-9, high + 1e-9):
        why = geometry.outside_stroke(P, angle, what="goal")
        assert why is not None and why.startswith(f"goal {angle:.4f} rad") and f"[{low:.4f}, {high:.4f}] rad" in why


def test_the_holding_pressure_is_the_force_over_the_piston_area_with_nothing_on_the_rod_side():
    """(F + p2 S2) / S1 to the last digits (no rounding to whole pascals); with the defaults,
    nothing on the rod side; a rod-side pressure without a rod acts on the whole piston."""
    force = 4863.0
    s1 = math.pi * 0.04**2 / 4.0
    assert geometry.holding_pressure_pa(force, 0.04) == pytest.approx(force / s1, rel=1e-14)
    assert geometry.holding_pressure_pa(force, 0.04, rod_side_pressure_pa=2e5) == pytest.approx(
        force / s1 + 2e5, rel=1e-14
    )
    assert geometry.holding_pressure_pa(force, 0.04, rod_diameter_m=0.022) == pytest.approx(force / s1, rel=1e-14)
