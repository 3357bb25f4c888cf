"""``boom-sim linearize``: the arguments of the linear model at an operating point (issue 24).

    boom-sim linearize --config config/default.yaml --rod-length-m 1.37 --out out/linear
    boom-sim linearize --config config/default.yaml --angle-deg 20 --payload-kg 150 --controller --out out/loop

The work is :mod:`boom_hydraulics.analysis.linearization`; this module only parses.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

from ..analysis.operating_point import rod_length_at_angle
from ..errors import ConfigError
from ..model.parameters import Parameters, with_updates


def register(
    sub: argparse._SubParsersAction, common: Callable, load: Callable[[argparse.Namespace], Parameters]
) -> None:
    """Add the ``linearize`` subcommand to boom-sim's ``sub`` parsers (``common``: --config, --set,
    --out; ``load``: boom-sim's parameter loading)."""
    p = sub.add_parser("linearize", help="the linear model at an operating point: modes, gains, Bode, margins")
    common(p, "folder for bode.csv, bode.png, linear_model.npz (and ringing.csv/png)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--rod-length-m", type=float, metavar="Q1", help="operating point: cylinder length in m")
    where.add_argument("--angle-deg", type=float, metavar="DEG", help="operating point: boom elevation in degrees")
    p.add_argument("--payload-kg", type=float, metavar="KG", help="payload at the boom tip (default: the config's)")
    p.add_argument("--opening", type=float, default=0.0, help="valve command held at the point: 0 centred (at rest), "
                   "else the steady motion at that opening (default 0)")  # fmt: skip
    p.add_argument("--controller", action="store_true", help="add the position controller's loop gain and margins")
    p.add_argument("--ringing", action="store_true", help="check against a simulated small step's ringing")
    p.set_defaults(handler=lambda args: run(args, load))


def run(args: argparse.Namespace, load: Callable[[argparse.Namespace], Parameters]) -> int:
    from ..analysis import linearization  # python-control loads in seconds: only for this subcommand

    params = load(args)
    if args.payload_kg is not None:
        params = with_updates(params, payload_mass_kg=args.payload_kg)
    if args.angle_deg is not None:
        if not math.isfinite(args.angle_deg):
            raise ConfigError(f"--angle-deg must be a finite angle in degrees, got {args.angle_deg}")
        q1 = rod_length_at_angle(params, math.radians(args.angle_deg))
    else:
        q1 = params.initial_length_m if args.rod_length_m is None else args.rod_length_m
    result = linearization.study(params, q1, args.opening, args.controller, args.ringing)
    for line in linearization.summary(result):
        print(line)
    names = linearization.write(result, Path(args.out))
    print(f"boom-sim linearize: {', '.join(names)} in {args.out}")
    return 0
