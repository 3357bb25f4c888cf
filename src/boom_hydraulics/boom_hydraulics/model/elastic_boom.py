"""The elastic boom: the rigid rotation alpha plus the boom's first bending mode (eq. E1-E9).

The boom is an Euler-Bernoulli cantilever clamped at the hinge O (the root between O and the
rod eye K, with its pivot bosses and the cylinder bracket, held by the cylinder), of length
L1 with its mass m1 spread evenly along it and the payload mb at the tip. Its deflection
normal to the boom, in the boom's frame that turns with alpha, is one assumed mode
(Rayleigh-Ritz): w(x, t) = phi(x) eta(t), phi(x) = (3 xi^2 - xi^3) / 2 with xi = x / L1, the
static shape under a tip load, so that eta is the tip's deflection (phi(L1) = 1, m). Then

    T = J alpha'^2 / 2 + m_c alpha' eta' + m_eta eta'^2 / 2                        (E1)
    V = M1 g sin(alpha) + S g cos(alpha) eta + k_eta eta^2 / 2                     (E2)
    m_c = 11/40 m1 L1 + mb L1,  m_eta = 33/140 m1 + mb,  S = 3/8 m1 + mb,
    k_eta = EI int phi''^2 dx = 3 EI / L1^3                                        (E3)

and Lagrange's equations with the cylinder's generalized force F_rod / k on alpha (the rod
acts at K, on the root: it does no work on eta) and a modal damping c_eta = 2 zeta
sqrt(k_eta m_eta) on eta:

    J alpha'' + m_c eta'' = F_rod / k - M_g + S g sin(alpha) eta                      (E4)
    m_c alpha'' + m_eta eta'' = -k_eta eta - c_eta eta' - S g cos(alpha)                (E5)

(S g cos(alpha): the weight's load on the mode). Eliminated:
eta'' = (J R_eta - m_c R_alpha) / (J m_eta - m_c^2) (E6), and the rod's acceleration is the
rigid one plus (S g sin(alpha) eta - m_c eta'') / (J k) (E7). Off (EI = 0), m_c, S and
k_eta are 0: eta stays 0 and the rigid equation is untouched, bit for bit.

Equations and conventions: docs/model.md, section "Elastic boom".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable
from .geometry import cos_boom_angle, lever_rad_per_m, sin_boom_angle

Num = Any  # float or numpy.ndarray

#: The mode shape's integrals over xi = x / L1 in [0, 1] (eq. E3): int phi, int xi phi,
#: int phi^2, int (phi'')^2 (with L1 = 1), for phi = (3 xi^2 - xi^3) / 2.
SHAPE_FIRST = 3.0 / 8.0
SHAPE_MOMENT = 11.0 / 40.0
SHAPE_SQUARE = 33.0 / 140.0
SHAPE_CURVATURE = 3.0


@jitable
def mode_shape(xi: Num) -> Num:
    """phi(xi) = (3 xi^2 - xi^3) / 2: the static deflection under a tip load over the tip's (eq. E1)."""
    return 0.5 * xi * xi * (3.0 - xi)


@jitable
def mode_slope(xi: Num) -> Num:
    """d(phi)/d(xi) = 3 xi (2 - xi) / 2: the deflected boom's slope times L1 over the tip deflection."""
    return 1.5 * xi * (2.0 - xi)


@jitable
def modal_stiffness_n_m(bending_stiffness_n_m2: Num, boom_length_m: Num) -> Num:
    """k_eta = 3 EI / L1^3 (eq. E3), N/m; 0 for a rigid boom (EI = 0)."""
    length = boom_length_m + (boom_length_m <= 0.0)  # a zero length has no mode (EI is then 0 too)
    return SHAPE_CURVATURE * bending_stiffness_n_m2 / (length * length * length)


@jitable
def modal_masses(boom_mass_kg: Num, payload_mass_kg: Num, boom_length_m: Num) -> tuple[Num, Num, Num]:
    """(m_c, kg m; m_eta, kg; S, kg): the coupling of the mode with the rotation, the mode's
    mass and its participation in the weight (eq. E3)."""
    coupling = (SHAPE_MOMENT * boom_mass_kg + payload_mass_kg) * boom_length_m
    modal = SHAPE_SQUARE * boom_mass_kg + payload_mass_kg
    return coupling, modal, SHAPE_FIRST * boom_mass_kg + payload_mass_kg


@jitable
def modal_damping_n_s_m(damping_ratio: Num, stiffness_n_m: Num, modal_mass_kg: Num, xp: ModuleType = math) -> Num:
    """c_eta = 2 zeta sqrt(k_eta m_eta) (eq. E5), N s/m."""
    return 2.0 * damping_ratio * xp.sqrt(stiffness_n_m * modal_mass_kg)


@jitable
def accelerations(
    rod_force_n: Num,
    lever: Num,
    moment_nm: Num,
    sin_alpha: Num,
    cos_alpha: Num,
    eta_m: Num,
    eta_rate_m_s: Num,
    inertia: Num,
    coupling: Num,
    modal_mass: Num,
    weight: Num,
    stiffness: Num,
    damping: Num,
) -> tuple[Num, Num]:
    """(eta'', m/s^2; the rod's acceleration beyond the rigid boom's, m/s^2) (eq. E4-E7).

    ``weight`` is S g (N), ``moment_nm`` the rigid weight moment M_g, ``damping`` c_eta."""
    r_alpha = rod_force_n / lever - moment_nm + weight * sin_alpha * eta_m  # E4's right side
    r_eta = -stiffness * eta_m - damping * eta_rate_m_s - weight * cos_alpha  # E5's right side
    eta_acc = (inertia * r_eta - coupling * r_alpha) / (inertia * modal_mass - coupling * coupling)  # E6
    return eta_acc, (weight * sin_alpha * eta_m - coupling * eta_acc) / (inertia * lever)  # E7


@jitable
def kinetic_energy_j(alpha_rate: Num, eta_rate_m_s: Num, coupling: Num, modal_mass: Num) -> Num:
    """The mode's share of T (eq. E1): m_c alpha' eta' + m_eta eta'^2 / 2, J."""
    return (coupling * alpha_rate + 0.5 * modal_mass * eta_rate_m_s) * eta_rate_m_s


@jitable
def potential_energy_j(eta_m: Num, cos_alpha: Num, weight: Num, stiffness: Num) -> Num:
    """The mode's share of V (eq. E2): the weight's S g cos(alpha) eta and the strain energy k_eta eta^2 / 2, J."""
    return (weight * cos_alpha + 0.5 * stiffness * eta_m) * eta_m


@jitable
def kinetic_power_w(
    alpha_rate: Num, alpha_acc: Num, eta_rate_m_s: Num, eta_acc: Num, coupling: Num, modal_mass: Num
) -> Num:
    """d/dt of :func:`kinetic_energy_j`, W."""
    return coupling * (alpha_acc * eta_rate_m_s + alpha_rate * eta_acc) + modal_mass * eta_rate_m_s * eta_acc


@jitable
def potential_power_w(
    alpha_rate: Num, eta_m: Num, eta_rate_m_s: Num, sin_alpha: Num, cos_alpha: Num, weight: Num, stiffness: Num
) -> Num:
    """d/dt of :func:`potential_energy_j`, W."""
    return weight * (cos_alpha * eta_rate_m_s - sin_alpha * alpha_rate * eta_m) + stiffness * eta_m * eta_rate_m_s


@jitable
def structural_loss_w(eta_rate_m_s: Num, damping: Num) -> Num:
    """c_eta eta'^2: the structural damping's dissipation (eq. E5), W."""
    return damping * eta_rate_m_s * eta_rate_m_s


@jitable
def fastest_rate(
    inertia: Num, coupling: Num, modal_mass: Num, stiffness: Num, damping: Num, xp: ModuleType = math
) -> Num:
    """A bound on the mode's eigenvalues, 1/s: with the rotation free its mass is
    m_f = (J m_eta - m_c^2) / J (below m_eta), its frequency sqrt(k_eta / m_f) and its damping
    rate c_eta / m_f; a damped oscillator's |lambda| is at most the sum of the two. (With a
    heavy tip mass m_f is small: the root turns under the payload, which stays put, and the
    structural damping makes that motion a fast, overdamped one.)"""
    free = (inertia * modal_mass - coupling * coupling) / inertia  # m_f
    return xp.sqrt(stiffness / free) + damping / free


@jitable
def hinge_force_n(
    alpha_rate: Num,
    alpha_acc: Num,
    eta_m: Num,
    eta_rate_m_s: Num,
    eta_acc: Num,
    sin_alpha: Num,
    cos_alpha: Num,
    rod_force_n: Num,
    rod_axial: Num,
    rod_normal: Num,
    total_mass: Num,
    first_moment: Num,
    participation: Num,
    gravity: Num,
) -> tuple[Num, Num]:
    """The force the column's hinge pin puts on the boom at O, in the boom's frame (x along
    the boom to the tip, z normal to it, up at alpha = 0), N (eq. E8).

    Newton for boom and payload: R = sum(m a) - m g - F_rod e_rod, with the acceleration of
    a point x of the boom, x e1 + w e2 turning at alpha', linear in w:
    a.e1 = -x alpha'^2 - 2 w' alpha' - w alpha'', a.e2 = x alpha'' + w'' - w alpha'^2.
    ``first_moment`` is M1 = m1 L1/2 + mb L1 (kg m), ``participation`` S (kg; 0 off),
    ``rod_axial``, ``rod_normal`` the rod's direction from its base to its eye in the boom's frame."""
    inertial_x = -first_moment * alpha_rate * alpha_rate - participation * (
        2.0 * alpha_rate * eta_rate_m_s + alpha_acc * eta_m
    )
    inertial_z = first_moment * alpha_acc + participation * (eta_acc - alpha_rate * alpha_rate * eta_m)
    return (
        inertial_x + total_mass * gravity * sin_alpha - rod_force_n * rod_axial,
        inertial_z + total_mass * gravity * cos_alpha - rod_force_n * rod_normal,
    )


@jitable
def static_deflection_m(p: Any, q1_m: float) -> float:
    """eta at rest at cylinder length ``q1_m`` for Parameters ``p``: -S g cos(alpha) / k_eta
    (eq. E5 with eta' = eta'' = alpha'' = 0), m; 0 for a rigid boom."""
    stiffness = modal_stiffness_n_m(p.boom_bending_stiffness_n_m2, p.boom_length_m)
    if stiffness <= 0.0:
        return 0.0
    _, _, participation = modal_masses(p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m)
    cos_alpha = cos_boom_angle(q1_m, p.a_m, p.b_m, p.support_height_m)
    return -participation * p.gravity_m_s2 * cos_alpha / stiffness


@jitable
def static_rod_force_share_n(p: Any, q1_m: float, eta_m: float) -> float:
    """What the rod must push beyond eq. 6's rigid boom to hold the boom bent by ``eta_m`` at
    rest at cylinder length ``q1_m``, -k S g sin(alpha) eta (eq. E4 with alpha'' = eta'' = 0:
    F_rod / k = M_g - S g sin(alpha) eta), N; 0 for a rigid boom (eta 0)."""
    _, _, participation = modal_masses(p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m)
    sin_alpha = sin_boom_angle(q1_m, p.a_m, p.b_m, p.support_height_m)
    return -lever_rad_per_m(q1_m, p.a_m, p.b_m) * participation * p.gravity_m_s2 * sin_alpha * eta_m
