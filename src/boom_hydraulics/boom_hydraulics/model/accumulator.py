"""A gas-charged (bladder or piston) accumulator on a line, through its connecting orifice (eq. A1-A7).

Its one state is its fill x = V_oil / V0: the oil it holds over its size, the gas volume at
pre-charge V0 (0: empty, the gas at its pre-charge p0). The gas is compressed along one
polytrope, p V_gas^n = p0 V0^n (eq. A1: n 1.0 isothermal, 1.4 adiabatic nitrogen), so its
pressure is a function of the fill, and the accumulator is a nonlinear gas spring behind an
orifice: it takes Q = K f(p_line - p_gas) from its line (eq. A3, the laminar-turbulent
orifice of the valve's paths, hydraulics.orifice_flow), dx/dt = Q / V0 (eq. A2).

Below its pre-charge the bladder is empty: the gas cannot expand beyond V0, and the
anti-extrusion poppet (a piston accumulator: the piston on its end cap) closes the port
to outflow. The poppet closes smoothly over the last :data:`CLOSING_FILL` of the fill
(a smoothstep: outflow only, eq. A4), so that the rates stay continuous and the fill never
goes below 0 in the exact solution; an inflow always passes.

The gas's energy relative to its pre-charge state, counted above tank pressure as every
hydraulic energy of the model, is the polytropic work E = V0 p0 I(x) - p_t V0 x (eq. A5),
whose rate is (p_gas - p_t) Q exactly; the orifice throttles (p_line - p_gas) Q >= 0
(eq. A6). Their sum is what the line gives, (p_line - p_t) Q. The small-signal gas
stiffness is dp/dV_oil = n p_gas / V_gas (eq. A7).

Functions work on floats and numpy arrays (``xp``); they are @jitable.

Equations and conventions: docs/model.md, section "Accumulator".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable
from .hydraulics import larger, orifice_flow, pos, smoothstep

Num = Any  # float or numpy.ndarray

#: The fill below which the poppet closes the port to outflow, smoothly to 0 at an empty
#: bladder (eq. A4): a regularisation of the poppet's stroke, 2 % of the size.
CLOSING_FILL = 0.02
#: The least gas share 1 - x the pressure law takes (a stage of a step far beyond any relief
#: pressure): p0 / 1e-3^n, far above any relief (eq. A1).
LEAST_GAS_SHARE = 1e-3
#: |(n - 1) ln(V0 / V_gas)| below which the polytropic work takes its series (eq. A5).
_SERIES = 1e-8


@jitable
def gas_pressure_pa(fill: Num, precharge_pa: Num, exponent: Num, xp: ModuleType = math) -> Num:
    """p_gas = p0 (V0 / V_gas)^n = p0 (1 - x)^-n, Pa, p0 at or below an empty bladder (eq. A1)."""
    share = larger(1.0 - pos(fill), LEAST_GAS_SHARE)
    return precharge_pa * xp.exp(-exponent * xp.log(share))  # eq. A1


@jitable
def gas_stiffness_pa_m3(fill: Num, precharge_pa: Num, exponent: Num, size_m3: Num, xp: ModuleType = math) -> Num:
    """dp_gas/dV_oil = n p_gas / V_gas, Pa/m^3: the gas spring's small-signal stiffness (eq. A7)."""
    share = larger(1.0 - pos(fill), LEAST_GAS_SHARE)
    return exponent * gas_pressure_pa(fill, precharge_pa, exponent, xp) / (size_m3 * share)  # eq. A7


@jitable
def port_flow_m3_s(
    fill: Num, line_pa: Num, gas_pa: Num, k_orifice: Num, transition_pa2: Num, xp: ModuleType = math
) -> Num:
    """Q into the accumulator from its line, m^3/s (eq. A3, A4): the orifice's laminar-turbulent
    flow, an outflow throttled by the poppet as the bladder empties (smoothstep over the last
    :data:`CLOSING_FILL`), an inflow free."""
    dp = line_pa - gas_pa
    inflow = 1.0 * (dp > 0.0)
    gate = inflow + (1.0 - inflow) * smoothstep(fill / CLOSING_FILL)  # eq. A4
    return orifice_flow(k_orifice, dp, transition_pa2, xp) * gate  # eq. A3


@jitable
def gas_energy_j(fill: Num, precharge_pa: Num, exponent: Num, size_m3: Num, tank_pa: Num, xp: ModuleType = math) -> Num:
    """The gas's energy relative to its pre-charge state, above tank pressure, J (eq. A5):
    the polytropic work V0 p0 I(x), I(x) = int_0^x (1 - s)^-n ds = ((1 - x)^(1-n) - 1) / (n - 1)
    (-ln(1 - x) for n = 1), less p_t V0 x; below an empty bladder p0 holds (its rate stays
    (p_gas - p_t) V0 dx/dt)."""
    full = pos(fill)
    log_ratio = -xp.log(larger(1.0 - full, LEAST_GAS_SHARE))  # ln(V0 / V_gas)
    z = (exponent - 1.0) * log_ratio
    series = 1.0 * (abs(z) < _SERIES)
    work_share = xp.expm1(z) / (z + series) * (1.0 - series) + (1.0 + 0.5 * z) * series  # (e^z - 1) / z
    polytropic = precharge_pa * log_ratio * work_share + precharge_pa * (fill - full)  # p0 I(x), eq. A5
    return size_m3 * (polytropic - tank_pa * fill)


@jitable
def fill_rate_1_s(flow_m3_s: Num, size_m3: Num) -> Num:
    """dx/dt = Q / V0, 1/s (eq. A2)."""
    return flow_m3_s / size_m3  # eq. A2


@jitable
def fastest_rate_1_s(
    fill: Num, precharge_pa: Num, exponent: Num, size_m3: Num, line_stiffness_pa_m3: Num, slope_m3_s_pa: Num
) -> Num:
    """The accumulator's fastest rate, 1/s: its orifice's laminar slope G = dQ/dp between the gas
    spring and the line's oil spring in series, G (n p_gas / V_gas + E / V_line)
    (physical.stiffness_rate)."""
    return slope_m3_s_pa * (gas_stiffness_pa_m3(fill, precharge_pa, exponent, size_m3) + line_stiffness_pa_m3)


@jitable
def initial_fill(line_pa: float, precharge_pa: float, exponent: float) -> float:
    """The fill at which the gas holds the line's pressure, 1 - (p0 / p)^(1/n); 0 where the
    line's pressure is at or below the pre-charge (an empty bladder) (eq. A1)."""
    if line_pa <= precharge_pa:
        return 0.0
    return 1.0 - (precharge_pa / line_pa) ** (1.0 / exponent)
