"""Hoses as lines with wave propagation between the drive's ports and the chambers.

Each of the two lines (A: the drive's port A to the piston chamber, B: port B to the rod
chamber) is a staggered finite-volume line of :data:`SEGMENTS` segments of length
l = L / N (docs/model.md, "Hoses", eq. H1-H6): pressure nodes at x = 0, l, ..., (N-1) l
(the port node holds half a segment's oil, the others a whole one; the last half segment's
oil is the chamber's) and a flow between each pair of neighbours (its oil's inertance
I = rho l / A and Hagen-Poiseuille resistance R = 128 mu l / (pi d^4)), the last flow
delivering into the chamber. The drive's Supply feeds the port node with its flow (computed
from the port node's pressure: the port pressure); the chamber receives the last flow.

Each node's state z is its pressure while it is full of liquid, as a chamber's
(hydraulics.chamber_state_rate with a fixed volume): p = max(z, p_cav), so a node that would
fall below the cavitation floor holds a void instead and the oil is conserved.

The line's oil compresses with K_eff, 1 / K_eff = 1 / E + 1 / K_wall (E the model's
bulk_modulus_pa, K_wall the hose wall's; eq. H1). Functions work on floats and numpy arrays.
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ..jit import jitable
from .hydraulics import chamber_pressure_pa, pos

Num = Any  # float or numpy.ndarray

#: Segments per line: 2 N states per line (N node pressures, N flows), 4 N for both lines.
SEGMENTS = 4
assert SEGMENTS == 4, "line() and line_energy() are written out for four segments"
#: The hoses' states: line A's node pressures (port first), its flows (port side first), then line B's.
STATE_NAMES = tuple(
    name
    for line in ("a", "b")
    for name in (*(f"hose_{line}_p{k}" for k in range(SEGMENTS)), *(f"hose_{line}_q{k + 1}" for k in range(SEGMENTS)))
)
STATE_SCALES = tuple(kind for _ in ("a", "b") for kind in ("pressure",) * SEGMENTS + ("flow",) * SEGMENTS)
STATE_UNITS = tuple(unit for _ in ("a", "b") for unit in ("Pa",) * SEGMENTS + ("m^3/s",) * SEGMENTS)
#: Where line B's states start among :data:`STATE_NAMES`.
LINE_B = 2 * SEGMENTS
#: Oil that one line holds, in whole segments' volumes: the chamber holds the last half segment.
NODE_SEGMENTS = SEGMENTS - 0.5


class HoseConstants(NamedTuple):
    """The hoses' constants (physical.Constants' last fields, under these names)."""

    hose_on: Num  # 1.0 with hoses, 0.0 without (the line's rates are then 0)
    hose_modulus: Num  # K_eff of the line's oil in the hose, Pa (eq. H1)
    hose_node_volume: Num  # A l: the oil of one segment, m^3 (the port node holds half of it)
    hose_inertance: Num  # I = rho l / A, Pa s^2 / m^3 (eq. H3)
    hose_resistance: Num  # R = 128 mu l / (pi d^4), Pa s / m^3 (eq. H3)
    hose_chamber_share: Num  # the line's oil the chambers' dead volumes give up, (N - 1/2) A l, m^3


@jitable
def effective_modulus_pa(oil_pa: Num, wall_pa: Num) -> Num:
    """K_eff of oil in a compliant hose: 1 / K_eff = 1 / K_oil + 1 / K_wall, Pa (eq. H1)."""
    return 1.0 / (1.0 / oil_pa + 1.0 / wall_pa)


@jitable
def wave_speed_m_s(modulus_pa: Num, density_kg_m3: Num) -> Num:
    """c = sqrt(K_eff / rho), m/s (eq. H2)."""
    return (modulus_pa / density_kg_m3) ** 0.5


@jitable
def hose_constants(
    length_m: float,
    diameter_m: float,
    wall_modulus_pa: float,
    viscosity_m2_s: float,
    oil_modulus_pa: float,
    density_kg_m3: float,
) -> HoseConstants:
    """The line's constants (eq. H1, H3). A length of 0 is no hose: the constants of a 1 m hose
    keep every rate finite, and ``hose_on`` 0 sets them to 0."""
    on = 1.0 if length_m > 0.0 else 0.0
    segment = (length_m if length_m > 0.0 else 1.0) / SEGMENTS
    area = 0.25 * math.pi * diameter_m * diameter_m
    volume = area * segment
    return HoseConstants(
        on,
        effective_modulus_pa(oil_modulus_pa, wall_modulus_pa),
        volume,
        density_kg_m3 * segment / area,
        128.0 * viscosity_m2_s * density_kg_m3 * segment / (math.pi * diameter_m**4),
        on * NODE_SEGMENTS * volume,
    )


class Line(NamedTuple):
    """One line at one instant (SI)."""

    port_pressure: Num  # the port node's pressure, Pa: what the drive's flow sees
    end_flow: Num  # the flow the line delivers into its chamber, m^3/s
    dz0: Num  # node state rates, Pa/s (eq. H4)
    dz1: Num
    dz2: Num
    dz3: Num
    dq1: Num  # flow rates, m^3/s^2 (eq. H5)
    dq2: Num
    dq3: Num
    dq4: Num
    oil_work: Num  # what the line's oil takes in: compression and kinetic energy, W (eq. H6)
    loss: Num  # friction, R sum q^2, W (eq. H6)
    energy_rate: Num  # d/dt of :func:`line_energy` along these rates, W


@jitable
def line(
    z: tuple,
    q: tuple,
    port_flow: Num,
    chamber_pa: Num,
    c: Any,
    p_cav: Num,
    p_tank: Num,
) -> Line:
    """The line with node states ``z`` (z0 at the port .. z3), flows ``q`` (q1 from node 0 to
    node 1 .. q4 from node 3 into the chamber), ``port_flow`` into its port node (the drive's)
    and its chamber at ``chamber_pa`` (eq. H4-H6); ``c`` has :class:`HoseConstants`' fields."""
    k, v, inertance, r = c.hose_modulus, c.hose_node_volume, c.hose_inertance, c.hose_resistance
    p0 = chamber_pressure_pa(z[0], p_cav)
    p1 = chamber_pressure_pa(z[1], p_cav)
    p2 = chamber_pressure_pa(z[2], p_cav)
    p3 = chamber_pressure_pa(z[3], p_cav)
    q1, q2, q3, q4 = q[0], q[1], q[2], q[3]
    dz0 = k / (0.5 * v) * (port_flow - q1)  # eq. H4: the port node holds half a segment
    dz1 = k / v * (q1 - q2)
    dz2 = k / v * (q2 - q3)
    dz3 = k / v * (q3 - q4)
    drop1 = p0 - p1 - r * q1  # eq. H5: I dq/dt = p_upstream - p_downstream - R q
    drop2 = p1 - p2 - r * q2
    drop3 = p2 - p3 - r * q3
    drop4 = p3 - chamber_pa - r * q4
    g0, g1, g2, g3 = p0 - p_tank, p1 - p_tank, p2 - p_tank, p3 - p_tank
    compression = g0 * (port_flow - q1) + g1 * (q1 - q2) + g2 * (q2 - q3) + g3 * (q3 - q4)
    kinetic = q1 * drop1 + q2 * drop2 + q3 * drop3 + q4 * drop4  # d/dt sum I q^2 / 2
    loss = r * (q1 * q1 + q2 * q2 + q3 * q3 + q4 * q4)
    stored = (
        0.5 * v * g0 * dz0 * (z[0] > p_cav)  # the pressure stands still at the floor
        + v * (g1 * dz1 * (z[1] > p_cav) + g2 * dz2 * (z[2] > p_cav) + g3 * dz3 * (z[3] > p_cav))
    ) / k
    return Line(
        p0,
        q4,
        *(dz0, dz1, dz2, dz3),
        *(drop1 / inertance, drop2 / inertance, drop3 / inertance, drop4 / inertance),
        compression + kinetic,
        loss,
        stored + kinetic,
    )


@jitable
def idle(zero: Num) -> Line:
    """A line without a hose: every field ``zero`` (0.0, or zeros shaped as a batch's)."""
    return Line(zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero)


@jitable
def line_energy(z: tuple, q: tuple, c: Any, p_cav: Num, p_tank: Num) -> Num:
    """What the line stores above tank pressure, J: its oil's compression V (p - p_t)^2 / (2 K_eff)
    per node and its flows' kinetic energy I q^2 / 2 (eq. H6)."""
    g0 = chamber_pressure_pa(z[0], p_cav) - p_tank
    g1 = chamber_pressure_pa(z[1], p_cav) - p_tank
    g2 = chamber_pressure_pa(z[2], p_cav) - p_tank
    g3 = chamber_pressure_pa(z[3], p_cav) - p_tank
    compression = c.hose_node_volume * (0.5 * g0 * g0 + g1 * g1 + g2 * g2 + g3 * g3) / (2.0 * c.hose_modulus)
    return compression + 0.5 * c.hose_inertance * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


@jitable
def line_rate_1_s(c: Any, chamber_stiffness: Num, xp: ModuleType = math) -> Num:
    """The line's fastest rate, 1/s, for the stepping's stability bound: its highest wave mode,
    about 2 c / l (the interior's 2 / sqrt(I C) with C = A l / K_eff), or the last flow between
    a node and a stiffer chamber (``chamber_stiffness`` = E / V), and its friction's R / I."""
    node = c.hose_modulus / c.hose_node_volume  # 1 / C of a whole segment
    end = node + pos(chamber_stiffness - node)
    return xp.sqrt(2.0 * (node + end) / c.hose_inertance) + c.hose_resistance / c.hose_inertance


@jitable
def port_stiffness(c: Any) -> Num:
    """K_eff / V of the port node (half a segment), Pa/m^3: how fast the drive's flow moves the port pressure."""
    return c.hose_modulus / (0.5 * c.hose_node_volume)


def line_frequencies_hz(length_m: float, modulus_pa: float, density_kg_m3: float) -> tuple[float, float]:
    """(c / (4 L), c / (2 L)), Hz: the first mode of a line with one end at a fixed pressure and
    the other blocked, and of a line blocked at both ends (eq. H7)."""
    c = math.sqrt(modulus_pa / density_kg_m3)
    return c / (4.0 * length_m), c / (2.0 * length_m)


def discrete_frequencies_hz(length_m: float, modulus_pa: float, density_kg_m3: float) -> tuple[float, float]:
    """The first modes of :data:`SEGMENTS` segments with the same two ends, Hz (eq. H8): the
    staggered line's dispersion omega = (2 c / l) sin(kappa l / 2) at kappa = pi / (2 L)
    (pressure-fixed end) and kappa = pi / L (both blocked)."""
    c = math.sqrt(modulus_pa / density_kg_m3)
    l = length_m / SEGMENTS  # noqa: E741
    quarter = 2.0 * c / l * math.sin(math.pi / (4.0 * length_m) * l)
    half = 2.0 * c / l * math.sin(math.pi / (2.0 * length_m) * l)
    return quarter / (2.0 * math.pi), half / (2.0 * math.pi)
