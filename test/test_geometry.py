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
