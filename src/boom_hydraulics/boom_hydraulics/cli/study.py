"""``boom-study paper``: the paper's figures regenerated from the model.

    boom-study paper --out docs/figures

Writes fig3_angles.png, fig4_static_force.png, fig5_holding_pressure.png (statics over
the stroke), fig8.png, fig9.png, fig10.png (the three dynamic cases in paper mode, with
physical mode for the same piston beside them), solver_study.png (error against step size
for Euler and RK4), and the numbers behind them as statics.csv and solver_study.csv.
Only these files are written into the folder, each whole or not at all; nothing else in
it is touched, so the figures can go next to others (docs/figures).
"""

from __future__ import annotations

import csv
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..analysis import plots, studies
from ..errors import BoomHydraulicsError, ConfigError
from ..files import check_apart, results_folder
from ..model import config
from ..programs import RaisingParser, run_main

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"  # the package's config/ (symlink in src)
DIAMETERS_M = (0.032, 0.04, 0.05, 0.063, 0.08)
CASES = {"fig8": "paper_fig8.yaml", "fig9": "paper_fig9.yaml", "fig10": "paper_fig10.yaml"}


def _config_dir() -> Path:
    for candidate in (CONFIG_DIR, Path.cwd() / "config"):
        if (candidate / "paper_fig8.yaml").is_file():
            return candidate
    raise BoomHydraulicsError("cannot find config/paper_fig8.yaml; run from the repository root")


def _line_figure(x, series, xlabel, ylabel, title, path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    for label, y in series:
        ax.plot(x, y, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def statics_figures(out: Path, params) -> None:
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


def dynamic_figures(out: Path, config_dir: Path, duration_s: float) -> None:
    for name, file in CASES.items():
        paper = config.load(config_dir / file)
        physical = studies.physical_counterpart(paper)
        runs = [
            (
                f"paper mode as printed (E = {paper.bulk_modulus_pa / 1e6:g} MPa)",
                studies.dynamic_case(paper, duration_s),
            ),
            (
                f"physical mode, same piston (E = {physical.bulk_modulus_pa / 1e9:g} GPa)",
                studies.dynamic_case(physical, duration_s),
            ),
        ]
        runs = [(label, tr.columns) for label, tr in runs]
        plots.dynamics(
            runs, out / f"{name}.png", title=f"{name}: piston D = {paper.piston_diameter_m * 1000:g} mm, valve open"
        )


def solver_figure(out: Path, config_dir: Path) -> None:
    params = config.load(config_dir / "paper_fig8.yaml")
    points = studies.solver_study(
        params, 1.0, {"euler": [1e-3, 3e-4, 1e-4, 3e-5, 1e-5], "rk4": [2e-2, 1e-2, 5e-3, 2e-3, 1e-3]}
    )
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for method in ("euler", "rk4"):
        pts = [p for p in points if p.method == method and p.error > 0]
        ax.loglog([p.dt_s for p in pts], [p.error for p in pts], "o-", label=method)
    ax.axhline(1e-6, color="grey", linestyle="--", linewidth=0.8, label="1e-6")
    ax.set_xlabel("time step dt [s]")
    ax.set_ylabel("relative error of q1 at t = 1 s [-]")
    ax.set_title("Solver study, paper fig. 8 case: error against step size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.savefig(out / "solver_study.png", dpi=110)
    plt.close(fig)
    with (out / "solver_study.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", "dt [s]", "relative error q1 [1]", "wall time [s]", "peak memory [MiB]"])
        for p in points:
            writer.writerow([p.method, p.dt_s, p.error if math.isfinite(p.error) else "nan", p.seconds, p.peak_mib])


def paper(out: Path, duration_s: float) -> None:
    if not (math.isfinite(duration_s) and 0 < duration_s <= 60):
        raise ConfigError(f"--duration must be a number of simulated seconds in (0, 60], got {duration_s:g}")
    config_dir = _config_dir()
    check_apart(out, [config_dir / name for name in ("default.yaml", *CASES.values())])
    from tqdm import tqdm

    stages = [
        ("statics", lambda tmp: statics_figures(tmp, config.load(config_dir / "default.yaml"))),
        ("fig8-fig10", lambda tmp: dynamic_figures(tmp, config_dir, duration_s)),
        ("solver study", lambda tmp: solver_figure(tmp, config_dir)),
    ]
    # progress on stderr where it is a terminal, as boom-sweep shows it
    with tqdm(total=len(stages), unit="stage", disable=None, file=sys.stderr) as progress, results_folder(out) as tmp:
        for name, stage in stages:
            progress.set_description(f"boom-study: {name}")
            stage(tmp)
            progress.update(1)


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-study", description="Regenerate the paper's studies.")
        sub = parser.add_subparsers(dest="study", required=True, parser_class=RaisingParser)
        p = sub.add_parser("paper", help="Figs. 3-5, 8-10 and the solver study")
        p.add_argument("--out", type=Path, default=Path("out/paper"), help="folder for the figures (default out/paper)")
        p.add_argument("--duration", type=float, default=3.0, help="simulated seconds of the dynamic cases (default 3)")
        args = parser.parse_args(argv)
        paper(args.out, args.duration)
        print(f"boom-study: figures in {args.out}")
        return 0

    return run_main("boom-study", body)


if __name__ == "__main__":
    sys.exit(main())
