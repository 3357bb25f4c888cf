"""``boom-sim linearize``'s work: the linear model at an operating point, its modes, gains,
frequency responses and the controller's margins, as lines to print and files to keep.

Files (in ``--out``, each whole or not at all): ``bode.csv`` and ``bode.png`` (the frequency
response of each output to the valve command, and with ``--controller`` the loop gain),
``linear_model.npz`` (A, B, C, D with the names of states, inputs and outputs, the operating
point, the eigenvalues and gains; ``control.ss(A, B, C, D)`` takes it up again) and, with
the ringing check, ``ringing.csv`` and ``ringing.png``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import control
import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np

from ..files import results_folder, write_csv_columns, write_npz
from ..model.parameters import Parameters
from . import linear_model as lm
from .operating_point import OperatingPoint, operating_point
from .ringing import SMALL_STEP, Ringing, ringing

#: The frequency axis of the Bode plot, around the hydraulic mode: this far below and above it.
DECADES_BELOW, DECADES_ABOVE = 3.0, 2.0
FREQUENCIES = 400
#: Units of the outputs in the plots and the CSV (pressures in MPa there).
PLOT_UNITS = {"q1": ("mm", 1e3), "v": ("mm/s", 1e3), "p1": ("MPa", 1e-6), "p2": ("MPa", 1e-6)}


@dataclass(frozen=True)
class Linearization:
    """Everything ``boom-sim linearize`` reports about one operating point."""

    model: lm.LinearModel
    loop: control.TransferFunction | None  # with --controller
    margins: lm.Margins | None
    ringing: Ringing | None  # with --ringing

    @property
    def point(self) -> OperatingPoint:
        return self.model.point


def study(
    params: Parameters, q1_m: float, opening: float = 0.0, controller: bool = False, check_ringing: bool = False
) -> Linearization:
    """Linearise at rod length ``q1_m`` with the valve at ``opening``; with ``controller`` the
    position loop's gain and margins, with ``check_ringing`` the simulated small step."""
    model = lm.linearize(operating_point(params, q1_m, opening))
    loop = lm.loop_gain(model) if controller else None
    return Linearization(
        model,
        loop,
        lm.margins(loop) if loop is not None else None,
        ringing(model.point) if check_ringing else None,
    )


def frequency_axis_rad_s(model: lm.LinearModel) -> np.ndarray:
    """The Bode plot's angular frequencies, rad/s: around the hydraulic mode (or the fastest mode)."""
    mode = model.hydraulic_mode()
    centre = abs(mode.eigenvalue) if mode else float(np.max(np.abs(np.linalg.eigvals(model.A))))
    return np.logspace(math.log10(centre) - DECADES_BELOW, math.log10(centre) + DECADES_ABOVE, FREQUENCIES)


def responses(result: Linearization) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(magnitude per unit of command in SI, phase in deg) of every output, and of the loop gain
    with the controller, over :func:`frequency_axis_rad_s` (control.frequency_response)."""
    omega = frequency_axis_rad_s(result.model)
    fr = control.frequency_response(result.model.system(), omega)
    out = {}
    for k, name in enumerate(lm.OUTPUT_NAMES):
        out[name] = (np.asarray(fr.magnitude[k, 0]), np.degrees(np.unwrap(np.asarray(fr.phase[k, 0]))))
    if result.loop is not None:
        loop = control.frequency_response(result.loop, omega)
        out["loop"] = (np.asarray(loop.magnitude).ravel(), np.degrees(np.unwrap(np.asarray(loop.phase).ravel())))
    return out


def _fmt_eigenvalue(lam: complex) -> str:
    if lam.imag > 0.0:
        return f"{lam.real:.4g} ± {lam.imag:.4g}j"
    return f"{lam.real:.4g}"


def summary(result: Linearization) -> list[str]:
    """The lines ``boom-sim linearize`` prints."""
    m, point = result.model, result.point
    p = point.params
    valve = "valve centred" if point.opening == 0.0 else f"valve at {point.opening:g}, v = {point.state[1]:.4g} m/s"
    lines = [
        f"linear model at q1 = {point.q1_m:.4f} m (alpha = {math.degrees(point.angle_rad):.2f} deg), payload "
        f"{p.payload_mass_kg:g} kg, {valve}: states {', '.join(result.model.state_names)}; input u; outputs "
        f"{', '.join(lm.OUTPUT_NAMES)}",
        "eigenvalues [1/s]: "
        + ", ".join(
            _fmt_eigenvalue(mode.eigenvalue)
            + (f" ({mode.natural_frequency_hz:.4g} Hz, zeta {mode.damping_ratio:.3g})" if mode.oscillatory else "")
            for mode in reversed(m.modes())
        ),
    ]
    mode = m.hydraulic_mode()
    if mode is None:
        lines.append("hydraulic mode: none oscillates here (every mode is real)")
    else:
        lines.append(f"hydraulic mode: {mode.natural_frequency_hz:.4g} Hz, damping ratio {mode.damping_ratio:.4g}")
    alone = lm.oil_spring_frequency_rad_s(p, point.q1_m) / (2 * math.pi)
    seals = lm.oil_spring_frequency_rad_s(p, point.q1_m, seals=True) / (2 * math.pi)
    mass = lm.effective_mass_at(p, point.q1_m)
    lines.append(
        f"formula sqrt(E S1^2/(m V1) + E S2^2/(m V2)): {alone:.4g} Hz (oil springs, m = {mass:.4g} kg at the rod); "
        f"with the seals' presliding stiffness F_s/z_ba: {seals:.4g} Hz"
    )
    units = dict((n, u) for n, u, _ in lm.OUTPUTS)
    quasi, dc = m.quasi_static_gains(), m.dc_gains()
    lines.append(
        "static gain per unit of command, the slow modes held: "
        + ", ".join(f"{n} {g:.4g} {units[n]}" for n, g in zip(lm.OUTPUT_NAMES, quasi))
        + "; "
        + _dc_gain_words(dc, units)
    )
    if point.opening == 0.0 and point.drift:
        lines.append(
            f"at rest p1 creeps by {point.drift:.4g} Pa/s (the load-holding valve's seat): the linear model holds "
            "for seconds, not hours"
        )
    if result.margins is not None:
        g = result.margins
        lines.append(
            f"position loop (Kp {p.control_position_gain_1_rad:g} 1/rad, Ki {p.control_integral_gain_1_rad_s:g} "
            f"1/(rad s)): gain margin {g.gain_margin:.4g} ({g.gain_margin_db:.3g} dB) at "
            f"{g.phase_crossover_hz:.4g} Hz, phase margin {g.phase_margin_deg:.4g} deg at the crossover "
            f"{g.crossover_hz:.4g} Hz"
        )
    if result.ringing is not None and mode is not None:
        r = result.ringing
        lines.append(
            f"small step ({SMALL_STEP:g}) simulated: ringing at {r.natural_frequency_hz:.4g} Hz, damping ratio "
            f"{r.damping_ratio:.4g} ({100 * (r.natural_frequency_hz / mode.natural_frequency_hz - 1):+.2f} % and "
            f"{100 * (r.damping_ratio / mode.damping_ratio - 1):+.2f} % from the linear model)"
        )
    return lines


def write(result: Linearization, out: Path) -> list[str]:
    """Write the results into folder ``out`` (only the files named in the module docstring);
    returns their names."""
    with results_folder(out) as staging:
        curves = responses(result)
        omega = frequency_axis_rad_s(result.model)
        _bode_csv(staging / "bode.csv", omega, curves)
        _bode_png(staging / "bode.png", omega, curves, result)
        _npz(staging / "linear_model.npz", result)
        if result.ringing is not None:
            _ringing_files(staging, result)
        names = sorted(item.name for item in staging.iterdir())
    return names


def _bode_csv(path: Path, omega: np.ndarray, curves: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    units = dict((n, u) for n, u, _ in lm.OUTPUTS)
    header = ["frequency [Hz]"]
    for name in curves:
        unit = f"{units[name]} per unit" if name in units else "1"  # the loop gain has none
        header += [f"{name} magnitude [{unit}]", f"{name} phase [deg]"]
    columns = [omega / (2 * math.pi)] + [c for pair in curves.values() for c in pair]
    write_csv_columns(path, header, columns)


def _bode_png(path: Path, omega: np.ndarray, curves: dict, result: Linearization) -> None:
    hz = omega / (2 * math.pi)
    names = list(curves)
    fig, axes = plt.subplots(2, len(names), figsize=(3.2 * len(names), 5.2), sharex=True, constrained_layout=True)
    for k, name in enumerate(names):
        magnitude, phase = curves[name]
        unit, scale = PLOT_UNITS.get(name, ("1", 1.0))
        top, bottom = axes[0, k], axes[1, k]
        top.loglog(hz, magnitude * scale, linewidth=1.2)
        top.set_title("loop gain L" if name == "loop" else f"{name} / u")
        top.set_ylabel("|L|" if name == "loop" else f"[{unit} per unit]")
        bottom.semilogx(hz, phase, linewidth=1.2)
        bottom.set_ylabel("phase [deg]")
        bottom.set_xlabel("frequency [Hz]")
        for ax in (top, bottom):
            ax.grid(True, which="both", alpha=0.3)
        if name == "loop" and result.margins is not None:
            g = result.margins
            top.axhline(1.0, color="grey", linewidth=0.8)
            top.axvline(g.crossover_hz, color="tab:red", linewidth=0.8, linestyle="--")
            bottom.axhline(-180.0, color="grey", linewidth=0.8)
            if math.isfinite(g.phase_crossover_hz):
                bottom.axvline(g.phase_crossover_hz, color="tab:red", linewidth=0.8, linestyle="--")
            top.text(0.02, 0.04, f"GM {g.gain_margin_db:.3g} dB\nPM {g.phase_margin_deg:.3g} deg",
                     transform=top.transAxes, fontsize="small")  # fmt: skip
    point = result.point
    mode = result.model.hydraulic_mode()
    title = (
        f"Linear model at q1 = {point.q1_m:.3f} m, payload {point.params.payload_mass_kg:g} kg, u = {point.opening:g}"
    )
    if mode is not None:
        title += f": {mode.natural_frequency_hz:.3g} Hz, zeta {mode.damping_ratio:.3g}"
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _npz(path: Path, result: Linearization) -> None:
    m = result.model
    arrays = {
        "A": m.A,
        "B": m.B,
        "C": m.C,
        "D": m.D,
        "state_names": np.array(m.state_names),
        "state_units": np.array(m.state_units),
        "input_names": np.array(["u"]),
        "output_names": np.array(lm.OUTPUT_NAMES),
        "output_units": np.array([u for _, u, _ in lm.OUTPUTS]),
        "operating_state": np.array([result.point.state[i] for i in m.states]),
        "opening": np.array(result.point.opening),
        "eigenvalues": np.linalg.eigvals(m.A),
        "dc_gains": m.dc_gains(),
        "quasi_static_gains": m.quasi_static_gains(),
    }
    if result.loop is not None:
        arrays["loop_numerator"] = np.asarray(result.loop.num[0][0], dtype=float)
        arrays["loop_denominator"] = np.asarray(result.loop.den[0][0], dtype=float)
    write_npz(path, arrays)


def _ringing_files(folder: Path, result: Linearization) -> None:
    r = result.ringing
    system = result.model.system()
    linear = control.forced_response(system, r.t_s, np.full(len(r.t_s), SMALL_STEP)).outputs[1]
    write_csv_columns(
        folder / "ringing.csv",
        ["t [s]", "v simulated [m/s]", "v fitted [m/s]", "v linear model [m/s]"],
        [r.t_s, r.velocity_m_s, r.fitted_m_s, linear],
    )
    fig, ax = plt.subplots(figsize=(8, 3.6), constrained_layout=True)
    base = result.point.state[1]
    ax.plot(r.t_s, (r.velocity_m_s - base) * 1e3, label="simulated (nonlinear model)", linewidth=1.4)
    ax.plot(r.t_s, linear * 1e3, label="linear model", linewidth=1.0, linestyle="--")
    ax.plot(r.t_s, (r.fitted_m_s - base) * 1e3, label="damped cosine fitted", color="black", linewidth=0.9,
            linestyle=":")  # fmt: skip
    ax.set_xlabel("time after the step [s]")
    ax.set_ylabel("rod velocity change [mm/s]")
    ax.set_title(
        f"Step of {SMALL_STEP:g} in the command: {r.natural_frequency_hz:.4g} Hz, zeta {r.damping_ratio:.3g} simulated"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(folder / "ringing.png", dpi=110)
    plt.close(fig)


def _dc_gain_words(dc: np.ndarray, units: dict[str, str]) -> str:
    """G(0) in words: its finite gains, and which outputs have none (a mode at s = 0)."""
    finite = [f"{n} {g:.4g} {units[n]}" for n, g in zip(lm.OUTPUT_NAMES, dc) if np.isfinite(g)]
    if len(finite) == len(dc):
        return "G(0): " + ", ".join(finite)
    none = [n for n, g in zip(lm.OUTPUT_NAMES, dc) if not np.isfinite(g)]
    head = f"G(0): {', '.join(finite)}; " if finite else ""
    return (
        f"{head}{', '.join(none)} have no static gain over all time (a mode at s = 0 integrates the command): "
        "take the gain with the slow modes held"
    )
