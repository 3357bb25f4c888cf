"""The crane's joints as the node publishes them (model/kinematics.py, docs/model.md
"Geometry"): the chain O-K-A cut open must close again, each point where eq. 1-5 put it, each
rate the derivative of its angle, and the length for an angle the inverse of eq. 4."""

from __future__ import annotations

import math

import pytest

from boom_hydraulics.model import geometry, kinematics
from boom_hydraulics.model.parameters import Parameters

P = Parameters()
A, B, H = P.a_m, P.b_m, P.support_height_m
LENGTHS_M = (1.07, 1.37, 1.71)  # low, the paper's start, high


def test_the_pivot_and_the_cylinder_base_sit_where_eq_3_puts_them():
    assert kinematics.COLUMN_FOOT_M == 0.2
    assert kinematics.pivot_height_m(P) == pytest.approx(0.2 + H, rel=1e-15)
    assert kinematics.pivot_xz(P) == (0.0, kinematics.pivot_height_m(P))
    ax, az = kinematics.base_xz(P)
    ox, oz = kinematics.pivot_xz(P)
    assert az == 0.2 and oz - az == pytest.approx(H, rel=1e-14)  # A is h below O
    assert math.hypot(ax - ox, az - oz) == pytest.approx(B, rel=1e-14)  # and b from it
    assert math.acos((oz - az) / B) == pytest.approx(math.acos(H / B), rel=1e-14)  # alpha2, eq. 3


def test_the_rod_eye_is_a_from_the_pivot_at_the_boom_angle_and_the_cylinder_closes_the_chain():
    for q1 in LENGTHS_M:
        alpha = geometry.boom_angle_rad(q1, A, B, H)
        kx, kz = kinematics.along_boom_xz(P, alpha, A)
        ox, oz = kinematics.pivot_xz(P)
        assert (kx - ox, kz - oz) == pytest.approx((A * math.cos(alpha), A * math.sin(alpha)), rel=1e-14)
        c = kinematics.chain(P, q1, 0.0)
        ax, az = kinematics.base_xz(P)
        # the rod's eye, q1 from A along the barrel's angle, meets K
        assert (ax + q1 * math.cos(c.barrel_rad), az + q1 * math.sin(c.barrel_rad)) == pytest.approx(
            (kx, kz), abs=1e-12
        )
        assert c.boom_rad == alpha and c.rod_m == q1
        assert kinematics.rod_length_m(P, alpha) == pytest.approx(q1, rel=1e-12)  # eq. 4 inverted


def test_each_rate_is_the_derivative_of_its_angle_at_the_rods_speed():
    v, dq = -0.23, 1e-6
    for q1 in LENGTHS_M:
        c = kinematics.chain(P, q1, v)
        ahead, behind = kinematics.chain(P, q1 + dq, 0.0), kinematics.chain(P, q1 - dq, 0.0)
        assert c.lever_rad_per_m == pytest.approx((ahead.boom_rad - behind.boom_rad) / (2 * dq), rel=1e-7)
        assert c.boom_rate_rad_s == pytest.approx(v * c.lever_rad_per_m, rel=1e-15)
        assert c.barrel_rate_rad_s == pytest.approx(v * (ahead.barrel_rad - behind.barrel_rad) / (2 * dq), rel=1e-6)
        assert c.rod_rate_m_s == v
        beta, rate, lever = kinematics.barrel_and_lever(q1, v, A, B, H)
        assert (beta, rate, lever) == (c.barrel_rad, c.barrel_rate_rad_s, c.lever_rad_per_m)
