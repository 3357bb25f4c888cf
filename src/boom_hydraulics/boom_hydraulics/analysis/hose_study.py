"""Which oscillation in the paper's Figs. 8-10 is the hydraulic-mechanical resonance and which
would be line waves (docs/hoses-study.md; `tools/with-env python tools/hoses-study` prints its table).

For each figure (its piston and printed modulus E) and for real oil with hoses, it gives:
the period of the oscillation in the reproduced figure (docs/figures/fig*.csv, paper mode as
printed: upward zero crossings of the rod's acceleration), the paper's own equations linearized
at their start (Fig. 7 listing: eq. 12 and 16, its doubled mass included), the physical model's
hydraulic mode (`linearize`, the valve centred at q1(0); at the printed moduli with the paper's
V1 and its friction, a force without stiffness, so without the seals' presliding), and the waves a hose of
:data:`HOSE_LENGTH_M` would carry at the same modulus, c / (4 L) and c / (2 L) (eq. H7).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..model import MODELS, hoses
from ..model.parameters import Parameters, with_updates
from .jacobian import CENTRAL, jacobian
from .linear_model import linearize
from .operating_point import operating_point

#: The paper's boom with its valve bank on the column: a hose run of 1 m from valve to cylinder.
HOSE_LENGTH_M = 1.0
#: Real mineral oil's bulk modulus (ISO VG 32-46: 1.4-1.8 GPa; docs/model.md, "Chambers").
OIL_MODULUS_PA = 1.5e9
#: The figures: name, piston diameter (m), the modulus they print (Pa).
FIGURES = (("Fig. 8", 0.04, 1.45e6), ("Fig. 9", 0.08, 1.45e6), ("Fig. 10", 0.08, 14.5e6))
FIGURE_DIR = Path(__file__).resolve().parents[4] / "docs" / "figures"


@dataclass(frozen=True)
class Row:
    """One case of the study: frequencies in Hz (nan where there is none)."""

    case: str
    piston_diameter_m: float
    modulus_pa: float  # the chambers' E
    figure_hz: float  # the paper-mode curve's oscillation in the reproduced figure
    paper_linear_hz: float  # the paper's equations linearized at their start (damped frequency)
    hydraulic_hz: float  # linearize: the physical model's hydraulic mode
    wave_speed_m_s: float  # c = sqrt(K_eff / rho) in the hose
    quarter_wave_hz: float  # c / (4 L)
    half_wave_hz: float  # c / (2 L)
    line_mode_hz: float  # linearize with hoses: the lowest line mode (nan without hoses in the model)


def figure_frequency_hz(name: str, mode: str = "paper") -> float:
    """1 / the mean interval between upward zero crossings of the rod's acceleration in the
    reproduced figure ``name``'s ``mode`` curve (docs/figures/fig8.csv ...), Hz."""
    path = FIGURE_DIR / f"fig{name.split()[-1]}.csv"
    with path.open() as handle:
        rows = [r for r in csv.DictReader(handle) if r["mode"] == mode]
    t = np.array([float(r["t [s]"]) for r in rows])
    a = np.array([float(r["a [m/s^2]"]) for r in rows])
    finite = np.isfinite(a) & (np.abs(a) < 10.0)  # Fig. 8's run leaves the geometry at its end
    t, a = t[finite], a[finite]
    up = np.nonzero((a[:-1] < 0.0) & (a[1:] >= 0.0))[0]
    crossings = t[up] - a[up] * (t[up + 1] - t[up]) / (a[up + 1] - a[up])
    return 1.0 / float(np.mean(np.diff(crossings))) if len(crossings) > 1 else math.nan


def paper_linear_hz(p: Parameters) -> float:
    """The paper's equations (paper mode, eq. 12 and 16 as the Fig. 7 listing) linearized in
    (q1, v, p1) at their start state with the valve open: the oscillating pair's Im(lambda) / 2 pi."""
    model = MODELS["paper"]
    c = model.constants(p)
    y0 = model.initial_state(p)

    def f(x: list) -> list:
        return list(model.derivative(0.0, [*x, *y0[3:]], c, 1.0)[:3])

    a = jacobian(f, y0[:3], [1.0, 1.0, p.supply_pressure_pa], [CENTRAL] * 3)
    values = np.linalg.eigvals(a)
    pair = values[values.imag > 0.0]
    return float(pair[0].imag) / (2 * math.pi) if len(pair) else math.nan


def _row(case: str, diameter_m: float, modulus_pa: float, figure: bool) -> Row:
    paper = with_updates(Parameters(), mode="paper", piston_diameter_m=diameter_m, bulk_modulus_pa=modulus_pa)
    paper = with_updates(paper, piston_dead_volume_m3=2.0e-5, spring_stiffness_n_m=2000.0, static_friction_n=100.0)
    physical = with_updates(Parameters(), piston_diameter_m=diameter_m, bulk_modulus_pa=modulus_pa)
    if figure:  # the paper's V1 (its chamber and pipelines, eq. 12): no room for hoses in the model;
        # its friction a force without stiffness (F_mp), so no seals' presliding stiffness either
        seals = {"static_friction_n": 0.0, "coulomb_friction_n": 0.0, "friction_presliding_damping_n_s_m": 0.0}
        physical = with_updates(physical, piston_dead_volume_m3=2.0e-5, **seals)
        k_eff = modulus_pa  # the printed E is already "the combined bulk modulus" of oil and lines
    else:  # real oil, with 1 m hoses in the model (their wall: hose_wall_modulus_pa)
        physical = with_updates(physical, hose_length_m=HOSE_LENGTH_M)
        k_eff = hoses.effective_modulus_pa(modulus_pa, physical.hose_wall_modulus_pa)
    model = linearize(operating_point(physical, physical.initial_length_m))
    mode = model.hydraulic_mode()
    fast = [m.natural_frequency_hz for m in model.modes() if m.oscillatory and m is not None]
    line_modes = [f for f in fast if f > 10.0 * mode.natural_frequency_hz] if not figure else []
    quarter, half = hoses.line_frequencies_hz(HOSE_LENGTH_M, k_eff, physical.density_kg_m3)
    return Row(
        case,
        diameter_m,
        modulus_pa,
        figure_frequency_hz(case) if figure else math.nan,
        paper_linear_hz(paper) if figure else math.nan,
        mode.natural_frequency_hz,
        hoses.wave_speed_m_s(k_eff, physical.density_kg_m3),
        quarter,
        half,
        min(line_modes) if line_modes else math.nan,
    )


def study() -> list[Row]:
    """The figures at their printed moduli, then the same pistons with real oil and 1 m hoses."""
    rows = [_row(name, d, e, True) for name, d, e in FIGURES]
    rows += [_row(f"real oil, D = {d * 1e3:.0f} mm", d, OIL_MODULUS_PA, False) for d in (0.04, 0.08)]
    return rows


def _number(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.3g}"


def markdown(rows: list[Row]) -> str:
    """The study as a markdown table (docs/hoses-study.md holds it; a test recomputes it)."""
    lines = [
        "| case | D (mm) | E (MPa) | figure (Hz) | paper's eqs. linearized (Hz) | hydraulic mode, linearize (Hz) "
        "| c (m/s) | c/(4L) (Hz) | c/(2L) (Hz) | line mode, linearize (Hz) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.case} | {r.piston_diameter_m * 1e3:.0f} | {r.modulus_pa / 1e6:.4g} | {_number(r.figure_hz)} "
            f"| {_number(r.paper_linear_hz)} | {_number(r.hydraulic_hz)} | {_number(r.wave_speed_m_s)} "
            f"| {_number(r.quarter_wave_hz)} | {_number(r.half_wave_hz)} | {_number(r.line_mode_hz)} |"
        )
    return "\n".join(lines) + "\n"
