"""The seal friction's element laws (docs/model.md, "Friction") at operating points their
equations fix: the paper's constant force, the Stribeck curve at rest, around v_st and sliding
fast, the LuGre bristles' rate and force at rest, in presliding and sliding steadily; each also on
a batch of sets (numpy arrays, xp=numpy), as boom-sweep runs them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import friction

#: Seals of the size the defaults have, N, N, m/s, m, N s/m, N s/m (no value is a special case:
#: none is 0, 1 or 2, so that a wrong operator or constant moves every result).
COULOMB_N, STATIC_N, STRIBECK_M_S, PRESLIDING_M, SIGMA1_N_S_M, VISCOUS_N_S_M = 420.0, 1500.0, 0.013, 3e-4, 2e4, 1100.0
#: Speeds from rest to sliding fast, both ways, m/s.
SPEEDS = (0.0, 0.004, -0.004, 0.013, 0.031, -0.031, 0.4)


def g_n(speed_m_s: float) -> float:
    """The Stribeck curve, g(v) = F_c + (F_s - F_c) exp(-(v / v_st)^2), N."""
    return COULOMB_N + (STATIC_N - COULOMB_N) * math.exp(-((speed_m_s / STRIBECK_M_S) ** 2))


def test_the_papers_friction_is_its_constant_force_plus_the_viscous_term_whatever_the_direction():
    for v in (0.23, -0.23, 0.0):
        assert friction.paper_friction_n(v, COULOMB_N, VISCOUS_N_S_M) == pytest.approx(
            COULOMB_N + VISCOUS_N_S_M * v, rel=1e-15
        )


def test_the_stribeck_curve_is_the_breakaway_force_at_rest_and_falls_to_coulomb_when_sliding():
    for v in SPEEDS:
        decay = friction.stribeck_decay(v, STRIBECK_M_S)
        assert decay == pytest.approx(math.exp(-((v / STRIBECK_M_S) ** 2)), rel=1e-14, abs=1e-300)
        assert friction.stribeck_level(decay, COULOMB_N, STATIC_N) == pytest.approx(g_n(v), rel=1e-14)
    assert friction.stribeck_level(friction.stribeck_decay(0.0, STRIBECK_M_S), COULOMB_N, STATIC_N) == STATIC_N
    assert friction.stribeck_level(friction.stribeck_decay(0.4, STRIBECK_M_S), COULOMB_N, STATIC_N) == pytest.approx(
        COULOMB_N, rel=1e-12
    )
    speeds = np.array(SPEEDS)  # a batch of sets
    decays = friction.stribeck_decay(speeds, STRIBECK_M_S, np)
    np.testing.assert_allclose(
        friction.stribeck_level(decays, COULOMB_N, STATIC_N), [g_n(v) for v in SPEEDS], rtol=1e-14
    )


def test_the_bristles_stand_still_at_rest_and_at_their_sliding_deflection_and_follow_lugre_between():
    """s' = (v - |v| s / r(v)) / z_ba with r = g / F_s: zero at rest, whatever s (no creep);
    zero sliding steadily at s = r sign(v); at s = 0 the rod's own speed over z_ba."""
    for v in SPEEDS:
        ratio = g_n(v) / STATIC_N
        for s in (0.0, 0.37, -0.52, 0.93):
            expected = (v - abs(v) * s / ratio) / PRESLIDING_M
            assert friction.bristle_rate(v, s, ratio, PRESLIDING_M) == pytest.approx(expected, rel=1e-13, abs=1e-9)
        assert friction.bristle_rate(v, math.copysign(ratio, v), ratio, PRESLIDING_M) == pytest.approx(0.0, abs=1e-6)
    assert friction.bristle_rate(0.0, 0.8, 0.9, PRESLIDING_M) == 0.0  # at rest nothing moves
    assert friction.bristle_rate(0.02, 0.0, 0.5, PRESLIDING_M) == pytest.approx(0.02 / PRESLIDING_M, rel=1e-15)
    assert friction.bristle_rate(-0.02, 0.25, 0.5, PRESLIDING_M) == pytest.approx(-0.03 / PRESLIDING_M, rel=1e-14)


def test_the_seal_force_is_the_stribeck_curve_sliding_steadily_and_spring_plus_damper_in_presliding():
    """F = F_s s + sigma1 exp(-(v / v_st)^2) z_ba s' + b_d v: sliding steadily (s = r sign(v),
    s' = 0) g(v) sign(v) + b_d v; in presliding a spring F_s / z_ba on the deflection z and a
    damper sigma1 + b_d (at rest s' = v / z_ba at s = 0)."""
    for v in (0.031, -0.031, 0.4):
        decay = friction.stribeck_decay(v, STRIBECK_M_S)
        ratio = friction.stribeck_level(decay, COULOMB_N, STATIC_N) / STATIC_N
        s = math.copysign(ratio, v)
        ds = friction.bristle_rate(v, s, ratio, PRESLIDING_M)
        force = friction.seal_friction_n(v, s, ds, STATIC_N, PRESLIDING_M, SIGMA1_N_S_M, decay, VISCOUS_N_S_M)
        assert force == pytest.approx(math.copysign(g_n(v), v) + VISCOUS_N_S_M * v, rel=1e-9)
    # presliding from rest: deflection z = 0.1 mm, a slow push (v << v_st, decay 1)
    z_m, v = 1e-4, 1e-5
    s = z_m / PRESLIDING_M
    ds = friction.bristle_rate(v, s, 1.0, PRESLIDING_M)
    force = friction.seal_friction_n(v, s, ds, STATIC_N, PRESLIDING_M, SIGMA1_N_S_M, 1.0, VISCOUS_N_S_M)
    spring = STATIC_N / PRESLIDING_M * z_m
    assert force == pytest.approx(spring + SIGMA1_N_S_M * PRESLIDING_M * ds + VISCOUS_N_S_M * v, rel=1e-13)
    at_rest_s0 = friction.seal_friction_n(v, 0.0, v / PRESLIDING_M, STATIC_N, PRESLIDING_M, SIGMA1_N_S_M, 1.0, 0.0)
    assert at_rest_s0 == pytest.approx(SIGMA1_N_S_M * v, rel=1e-13)  # the damper sigma1 alone
    # the damping fades with the Stribeck decay: half the decay, half the sigma1 term
    damped = friction.seal_friction_n(0.0, 0.0, 2.0, STATIC_N, PRESLIDING_M, SIGMA1_N_S_M, 0.5, VISCOUS_N_S_M)
    assert damped == pytest.approx(SIGMA1_N_S_M * 0.5 * PRESLIDING_M * 2.0, rel=1e-14)
    forces = friction.seal_friction_n(  # a batch of sets
        np.array([0.031, -0.4]),
        np.array([0.3, -0.28]),
        np.array([5.0, -7.0]),
        STATIC_N,
        PRESLIDING_M,
        SIGMA1_N_S_M,
        np.array([0.6, 0.0]),
        VISCOUS_N_S_M,
    )
    np.testing.assert_allclose(
        forces,
        [
            STATIC_N * 0.3 + SIGMA1_N_S_M * 0.6 * PRESLIDING_M * 5.0 + VISCOUS_N_S_M * 0.031,
            STATIC_N * -0.28 + VISCOUS_N_S_M * -0.4,
        ],
        rtol=1e-14,
    )
