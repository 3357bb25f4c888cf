"""The paper's figures drawn from the model (``boom-study paper``): Figs. 3-5 (statics over the
stroke), Figs. 8-10 (the three dynamic cases in paper mode as printed, physical mode beside
them) and the solver study, each with the numbers behind it in a CSV, so that a test can
tell when the committed figures no longer show what the code computes."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..model import config
from ..model.parameters import Parameters
from ..solve.simulation import Trajectory
from . import plots, studies

#: The piston diameters of Fig. 5, m.
DIAMETERS_M = (0.032, 0.04, 0.05, 0.063, 0.08)
#: The dynamic cases: figure name -> its params file in config/.
CASES = {"fig8": "paper_fig8.yaml", "fig9": "paper_fig9.yaml", "fig10": "paper_fig10.yaml"}
#: Simulated seconds of the dynamic cases, unless boom-study's --duration says otherwise.
DURATION_S = 3.0
#: The samples a dynamic case's CSV keeps: every this many steps of the run (and its last).
CSV_EVERY = 10
#: Significant digits of a dynamic case's CSV: far more than a figure shows, and than the test that
#: compares it with a fresh run needs (test_studies).
CSV_DIGITS = 10
#: The signals of a dynamic case's CSV: (signal, unit).
CASE_SIGNALS = (("t", "s"), ("q1", "m"), ("v", "m/s"), ("a", "m/s^2"), ("p1", "Pa"))
#: The solver study: the methods (in words) and their time steps, s.
SOLVER_STEPS_S = {"euler": [1e-3, 3e-4, 1e-4, 3e-5, 1e-5], "rk4": [2e-2, 1e-2, 5e-3, 2e-3, 1e-3]}
METHOD_WORDS = {"euler": "explicit Euler (1st order)", "rk4": "Runge-Kutta RK4 (4th order)"}


def _line_figure(x, series, xlabel, ylabel, title, path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    for label, y in series:
        ax.plot(x, y, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def statics_figures(out: Path, params: Parameters) -> None:
    """Figs. 3-5 and statics.csv into ``out``."""
    s = studies.statics(params, DIAMETERS_M)
    q1 = s["q1"]
    _line_figure(
        q1,
        [
            ("boom elevation alpha (eq. 4)", np.degrees(s["alpha"])),
            ("rod-boom angle phi (eq. 5)", np.degrees(s["phi"])),
        ],
        "cylinder length q1 [m]",
        "angle [deg]",
        "Fig. 3: boom and rod angles over the stroke",
        out / "fig3_angles.png",
    )
    _line_figure(
        q1,
        [(f"m1 = {params.boom_mass_kg:g} kg, mb = {params.payload_mass_kg:g} kg", s["static_force"] / 1e3)],
        "cylinder length q1 [m]",
        "static rod force F [kN]",
        "Fig. 4: static rod force (eq. 6)",
        out / "fig4_static_force.png",
    )
    pressures = [(f"D = {d * 1000:g} mm", s[f"holding_pressure_D{d * 1000:g}mm"] / 1e6) for d in DIAMETERS_M]
    _line_figure(
        q1,
        pressures,
        "cylinder length q1 [m]",
        "holding pressure p1 [MPa]",
        "Fig. 5: piston-chamber pressure holding the boom",
        out / "fig5_holding_pressure.png",
    )
    with (out / "statics.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(studies.statics_header(s))
        writer.writerows(np.column_stack(list(s.values())).tolist())


def dynamic_runs(paper: Parameters, duration_s: float) -> list[tuple[str, str, Trajectory]]:
    """A dynamic case: (mode, legend label, run) of paper mode as printed and of physical mode
    with the same piston (studies.physical_counterpart), the valve fully open."""
    physical = studies.physical_counterpart(paper)
    return [
        (
            "paper",
            f"paper mode as printed (E = {paper.bulk_modulus_pa / 1e6:g} MPa)",
            studies.dynamic_case(paper, duration_s),
        ),
        (
            "physical",
            f"physical mode, same piston (E = {physical.bulk_modulus_pa / 1e9:g} GPa)",
            studies.dynamic_case(physical, duration_s),
        ),
    ]


def case_table(runs: Sequence[tuple[str, str, Trajectory]]) -> tuple[list[str], list[list[object]]]:
    """The numbers behind a dynamic case's figure: its header and rows, one row per kept sample
    (every :data:`CSV_EVERY`-th and the last) of each run, named by its mode."""
    header = ["mode", *(f"{name} [{unit}]" for name, unit in CASE_SIGNALS)]
    rows: list[list[object]] = []
    for mode, _, run in runs:
        n = len(run["t"])
        kept = sorted({*range(0, n, CSV_EVERY), n - 1})
        columns = [np.asarray(run[name], dtype=float)[kept] for name, _ in CASE_SIGNALS]
        rows += [[mode, *(float(c[i]) for c in columns)] for i in range(len(kept))]
    return header, rows


def dynamic_figures(out: Path, config_dir: Path, duration_s: float) -> None:
    """Figs. 8-10 (fig8.png, ...) and the numbers behind each (fig8.csv, ...) into ``out``."""
    for name, file in CASES.items():
        paper = config.load(config_dir / file)
        runs = dynamic_runs(paper, duration_s)
        number = name.removeprefix("fig")
        plots.dynamics(
            [(label, run.columns) for _, label, run in runs],
            out / f"{name}.png",
            title=f"Fig. {number}: piston D = {paper.piston_diameter_m * 1000:g} mm, valve fully open",
        )
        header, rows = case_table(runs)
        with (out / f"{name}.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(header)
            writer.writerows([mode, *(f"{v:.{CSV_DIGITS}g}" for v in values)] for mode, *values in rows)


def solver_figure(out: Path, config_dir: Path) -> None:
    """The solver study (solver_study.png, solver_study.csv) into ``out``: the error of q1
    after 1 s of the Fig. 8 case against the time step, for Euler and RK4."""
    params = config.load(config_dir / "paper_fig8.yaml")
    points = studies.solver_study(params, 1.0, SOLVER_STEPS_S)
    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    for method in SOLVER_STEPS_S:
        pts = [p for p in points if p.method == method and p.error > 0]
        ax.loglog([p.dt_s for p in pts], [p.error for p in pts], "o-", label=METHOD_WORDS[method])
    ax.axhline(1e-6, color="grey", linestyle="--", linewidth=0.8, label="relative error 1e-6")
    ax.set_xlabel("time step dt [s]")
    ax.set_ylabel("relative error of q1 at t = 1 s [-]")
    ax.set_title("Solver study, the paper's Fig. 8 case: error against step size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(out / "solver_study.png", dpi=110)
    plt.close(fig)
    with (out / "solver_study.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", "dt [s]", "relative error q1 [1]", "wall time [s]", "peak memory [MiB]"])
        for p in points:
            writer.writerow([p.method, p.dt_s, p.error if math.isfinite(p.error) else "nan", p.seconds, p.peak_mib])
