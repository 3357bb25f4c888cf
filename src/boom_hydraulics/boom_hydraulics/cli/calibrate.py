"""``boom-calibrate``: fit model parameters so that a re-simulation of a bag matches its recorded signals.

    boom-calibrate bags/<run> --fit bulk_modulus_pa,orifice_diameter_m,coulomb_friction_n --out out/calibrated
    boom-calibrate machine.mcap --config config/default.yaml --fit bulk_modulus_pa --weight p2=0.5 --out out/fit

The arguments only; what a calibration does, and what it refuses, is told in
:mod:`boom_hydraulics.calibration.fit`. Exit status 0 for a fit to trust, 3 for one that did
not converge, 4 for one that cannot tell a fitted parameter (its files written all the same,
marked; :mod:`boom_hydraulics.calibration.verdict`), 2 for what it refuses, 1 for a failure.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path

from ..errors import ConfigError
from ..files import check_apart
from ..model import config
from ..programs import DefaultsFormatter, RaisingParser, run_main, summary


def _names(text: str) -> list[str]:
    return [name.strip() for name in text.split(",") if name.strip()]


def _weights(items: Sequence[str]) -> dict[str, float]:
    weights = {}
    for item in items:
        name, value = config.parse_assignment(item)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"--weight {item}: the weight must be a number")
        weights[name] = float(value)
    return weights


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-calibrate", description=summary(__doc__), formatter_class=DefaultsFormatter)
        parser.add_argument("bag", type=Path, help="bag folder or .mcap file with the run's commands and signals")
        parser.add_argument("--fit", required=True, metavar="NAMES", help="parameters to fit, comma-separated")
        parser.add_argument("--config", type=Path, help="params YAML replacing the recorded parameters (required "
                            "for a bag that boom_sim did not record)")  # fmt: skip
        parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="change one start value")
        parser.add_argument("--signals", default="q1,p1,p2", help="recorded signals to match, comma-separated")
        parser.add_argument("--weight", action="append", default=[], metavar="SIGNAL=W",
                            help="weight of one signal (default 1 each)")  # fmt: skip
        parser.add_argument("--command-timeout", type=float, default=0.0, metavar="S",
                            help="a bag without run description: the valve closes S s after the last command "
                            "(0: never)")  # fmt: skip
        parser.add_argument("--max-evaluations", type=int, default=200, metavar="N", help="re-simulations per stage")
        parser.add_argument("--starts", type=int, default=4, metavar="N", help="starts of the fit: the given one and "
                            "N - 1 spread over a decade around it and the default")  # fmt: skip
        parser.add_argument("--workers", type=int, metavar="N", help="processes that re-simulate side by side "
                            "(default: one per core)")  # fmt: skip
        parser.add_argument("--out", type=Path, required=True, help="folder for the results")
        args = parser.parse_args(argv)
        if args.max_evaluations < 1:
            raise ConfigError(f"--max-evaluations must be >= 1, got {args.max_evaluations}")
        if args.starts < 1:
            raise ConfigError(f"--starts must be >= 1, got {args.starts}")
        if args.workers is not None and args.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {args.workers}")
        if not (args.command_timeout >= 0 and math.isfinite(args.command_timeout)):
            raise ConfigError(f"--command-timeout must be >= 0 s, got {args.command_timeout}")
        check_apart(args.out, [args.bag] + ([args.config] if args.config else []))
        from ..calibration import fit, report  # scipy and the bags: after the arguments are known good

        overrides = dict(config.parse_assignment(s) for s in args.set)
        problem = fit.prepare(
            args.bag, _names(args.fit), args.config, overrides, _names(args.signals), _weights(args.weight),
            args.command_timeout,
        )  # fmt: skip
        result = fit.calibrate(problem, args.max_evaluations, args.workers, args.starts)
        for line in report.summary(result):
            print(line)
        names = report.write(result, args.out)
        marked = " (marked: do not use as they are)" if result.findings else ""
        print(f"boom-calibrate: {', '.join(names)} in {args.out}{marked}")
        for line in report.verdict_lines(result):
            print(f"boom-calibrate: {line}", file=sys.stderr)
        return result.exit_status

    return run_main("boom-calibrate", body)


if __name__ == "__main__":
    sys.exit(main())
