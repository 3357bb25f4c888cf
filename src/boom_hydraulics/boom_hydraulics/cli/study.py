"""``boom-study paper``: the paper's figures regenerated from the model.

    boom-study paper --out docs/figures

Writes fig3_angles.png, fig4_static_force.png, fig5_holding_pressure.png (statics over
the stroke), fig8.png, fig9.png, fig10.png (the three dynamic cases in paper mode, with
physical mode for the same piston beside them), solver_study.png (error against step size
for Euler and RK4), and the numbers behind them as statics.csv, fig8.csv, fig9.csv,
fig10.csv and solver_study.csv (analysis.paper_figures draws them).
Only these files are written into the folder, each whole or not at all; nothing else in
it is touched, so the figures can go next to others (docs/figures).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path

from ..analysis import paper_figures
from ..errors import BoomHydraulicsError, ConfigError
from ..files import check_apart, results_folder
from ..model import config
from ..programs import RaisingParser, run_main

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"  # the package's config/ (symlink in src)
CASES = paper_figures.CASES


def _config_dir() -> Path:
    for candidate in (CONFIG_DIR, Path.cwd() / "config"):
        if (candidate / "paper_fig8.yaml").is_file():
            return candidate
    raise BoomHydraulicsError("cannot find config/paper_fig8.yaml; run from the repository root")


def paper(out: Path, duration_s: float) -> None:
    if not (math.isfinite(duration_s) and 0 < duration_s <= 60):
        raise ConfigError(f"--duration must be a number of simulated seconds in (0, 60], got {duration_s:g}")
    config_dir = _config_dir()
    check_apart(out, [config_dir / name for name in ("default.yaml", *CASES.values())])
    from tqdm import tqdm

    stages = [
        ("statics", lambda tmp: paper_figures.statics_figures(tmp, config.load(config_dir / "default.yaml"))),
        ("fig8-fig10", lambda tmp: paper_figures.dynamic_figures(tmp, config_dir, duration_s)),
        ("solver study", lambda tmp: paper_figures.solver_figure(tmp, config_dir)),
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
        p.add_argument(
            "--duration",
            type=float,
            default=paper_figures.DURATION_S,
            help=f"simulated seconds of the dynamic cases (default {paper_figures.DURATION_S:g})",
        )
        args = parser.parse_args(argv)
        paper(args.out, args.duration)
        print(f"boom-study: figures in {args.out}")
        return 0

    return run_main("boom-study", body)


if __name__ == "__main__":
    sys.exit(main())
