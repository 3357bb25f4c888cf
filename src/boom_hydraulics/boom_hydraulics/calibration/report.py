"""What ``boom-calibrate`` prints and keeps: the fitted values with their intervals, the
residual before and after, a plot of the recorded and fitted signals and the params file.

Files (in ``--out``, each whole or not at all): ``calibrated.yaml`` (every parameter, the
fitted ones changed: ``boom_sim --ros-args --params-file`` and ``boom-sim --config`` take it as
it is), ``calibration.csv`` (each fitted parameter: start, fitted, interval, whether at a
bound, and the verdict on it), ``signals.csv`` (each recorded sample with the start and the
fitted simulation) and ``fit.png``.

A fit that did not converge or cannot tell a parameter (:mod:`.verdict`) is written all the
same, whole, to look into: ``calibrated.yaml`` then begins with a comment line saying so and
why, ``calibration.csv``'s verdict column names it, and ``fit.png``'s title says it.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np

from ..files import csv_cell, results_folder, write_bytes, write_csv
from ..model import config
from ..model.parameters import as_dict, describe, from_mapping
from .fit import Fit
from .signals import UNITS
from .uncertainty import LEVEL

#: How the signals are shown: unit and scale.
SHOWN = {"m": ("mm", 1e3), "Pa": ("MPa", 1e-6), "m/s": ("mm/s", 1e3)}


def _unit(name: str) -> str:
    return describe(name)["unit"]


def _clocks(fit: Fit) -> str:
    clocks = sorted({s.clock for s in fit.problem.signals.values()})
    return " and ".join(clocks)


def verdict_lines(fit: Fit) -> list[str]:
    """One line per reason not to trust the fit: 'not identifiable: orifice_diameter_m: ...'."""
    return [f"{f.label}: {f.subject}: {f.why}" for f in fit.findings]


def _spread(fit: Fit) -> str:
    """'4 starts; the ends: bulk_modulus_pa 9.98e+08 .. 1.001e+09 Pa, ...'."""
    if len(fit.ends) < 2:
        return "1 start"
    good = sum(1 for e in fit.ends if e.cost <= fit.ends[0].cost * 1.01 + 1e-12)
    ranges = ", ".join(
        f"{n} {min(e.end[n] for e in fit.ends):.4g} .. {max(e.end[n] for e in fit.ends):.4g} {_unit(n)}"
        for n in fit.problem.names
    )
    return f"{len(fit.ends)} starts, {good} ending within 1 % of the best sum of squares; their ends: {ranges}"


def summary(fit: Fit) -> list[str]:
    """The lines ``boom-calibrate`` prints."""
    p = fit.problem
    lines = [
        f"{p.bag}: fitted {', '.join(p.names)} to {', '.join(p.signals)} "
        f"({', '.join(f'{len(s.values)} {n}' for n, s in p.signals.items())} samples at their {_clocks(fit)}); "
        f"{fit.evaluations} re-simulations in {fit.seconds:.1f} s"
    ]
    for name in p.names:
        low, high = fit.interval[name]
        unit = _unit(name)
        bound = " (at its bound)" if fit.at_bound[name] else ""
        width = "" if math.isfinite(high - low) else " (not identifiable from these signals)"
        lines.append(
            f"  {name}: {fit.start[name]:.6g} -> {fit.fitted[name]:.6g} {unit}, {LEVEL:.0%} interval "
            f"[{low:.6g}, {high:.6g}]{bound}{width}"
        )
    lines.append(
        "  RMS residual before -> after: "
        + ", ".join(f"{n} {fit.rms_before[n]:.4g} -> {fit.rms_after[n]:.4g} {UNITS[n]}" for n in p.signals)
        + f"; noise {', '.join(f'{n} {p.noise[n]:.3g}' for n in p.signals)}"
        + f"; sum of squares in units of the noise {fit.cost_before:.4g} -> {fit.cost_after:.4g}"
    )
    lines.append(f"  {_spread(fit)}")
    return lines


def _mark(fit: Fit) -> str | None:
    """The line a results file of an untrustworthy fit begins with, or None."""
    if not fit.findings:
        return None
    first = fit.findings[0]
    return f"{first.label.upper()} (exit status {fit.exit_status}): {first.subject}: {first.why}; do not use as it is"


def _verdict(fit: Fit, name: str) -> str:
    said = [f"{f.label}: {f.why}" for f in fit.findings if f.subject == name]
    if said:
        return "; ".join(said)
    return "ok" if not fit.findings else "ok, but the fit is not: " + fit.findings[0].label


def write(fit: Fit, out: Path) -> list[str]:
    """Write the results into folder ``out`` (only the files named in the module docstring)."""
    with results_folder(out) as staging:
        _params_file(staging / "calibrated.yaml", fit)
        _parameters_csv(staging / "calibration.csv", fit)
        _signals_csv(staging / "signals.csv", fit)
        _plot(staging / "fit.png", fit)
        names = sorted(item.name for item in staging.iterdir())
    return names


def _params_file(path: Path, fit: Fit) -> None:
    p = fit.problem
    params = from_mapping(p.values | p.overrides | fit.fitted)  # validated: the node and boom-sim load it
    mark = _mark(fit)
    header = ([f"# {mark}"] if mark else []) + [f"# boom-calibrate: {', '.join(p.names)} fitted to {p.bag}"]
    for name in p.names:
        low, high = fit.interval[name]
        header.append(f"#   {name}: {fit.fitted[name]!r} {_unit(name)} ({LEVEL:.0%}: {low:.6g} .. {high:.6g})")
    header.append("# every other parameter as the re-simulation ran it")
    write_bytes(path, ("\n".join(header) + "\n" + config.dumps(as_dict(params))).encode())


def _parameters_csv(path: Path, fit: Fit) -> None:
    rows = []
    for name in fit.problem.names:
        low, high = fit.interval[name]
        row = [name, _unit(name), fit.start[name], fit.fitted[name], low, high, fit.at_bound[name], _verdict(fit, name)]
        rows.append(row)
    header = ["parameter", "unit", "start", "fitted", f"low {LEVEL:.0%}", f"high {LEVEL:.0%}", "at bound", "verdict"]
    write_csv(path, header, ([csv_cell(v) for v in row] for row in rows))


def _signals_csv(path: Path, fit: Fit) -> None:
    p = fit.problem

    def rows():
        for name, signal in p.signals.items():
            start = fit.initial[name] if fit.initial is not None else np.full(len(signal.values), math.nan)
            final = fit.final[name] if fit.final is not None else np.full(len(signal.values), math.nan)
            for t, recorded, a, b in zip(p.times_s[name], signal.values, start, final):
                yield [name, csv_cell(t), csv_cell(recorded), csv_cell(a), csv_cell(b)]

    write_csv(path, ["signal", "t [s]", "recorded", "start", "fitted"], rows())


def _plot(path: Path, fit: Fit) -> None:
    p = fit.problem
    names = list(p.signals)
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 2.4 * len(names)), sharex=True, constrained_layout=True)
    axes = np.atleast_1d(axes)
    for ax, name in zip(axes, names):
        unit, scale = SHOWN.get(UNITS[name], (UNITS[name], 1.0))
        t = p.times_s[name]
        ax.plot(t, p.signals[name].values * scale, ".", markersize=2.0, color="0.35", label="recorded")
        if fit.initial is not None:
            ax.plot(t, fit.initial[name] * scale, linewidth=0.9, linestyle="--", color="tab:orange", label="start")
        if fit.final is not None:
            ax.plot(t, fit.final[name] * scale, linewidth=1.1, color="tab:blue", label="fitted")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time since the run's origin [s]")
    fitted = ", ".join(f"{n} {fit.fitted[n]:.4g}" for n in p.names)
    mark = f"\n{fit.findings[0].label.upper()}: {fit.findings[0].subject}" if fit.findings else ""
    fig.suptitle(f"{p.bag.name}\nfitted: {fitted}{mark}", fontsize="medium")
    fig.savefig(path, dpi=110)
    plt.close(fig)
