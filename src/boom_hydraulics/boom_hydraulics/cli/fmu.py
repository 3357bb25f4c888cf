"""``boom-sim fmu``: the physical drive as an FMI 2.0 co-simulation FMU (docs/fmu.md).

boom-sim fmu --config config/default.yaml --out boom_drive.fmu
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from ..model.parameters import Parameters


def register(
    sub: argparse._SubParsersAction, common: Callable, load: Callable[[argparse.Namespace], Parameters]
) -> None:
    """Add the ``fmu`` subcommand to boom-sim's ``sub`` parsers (``common``: --config, --set,
    --out; ``load``: boom-sim's parameter loading, which refuses an output that is or holds the config)."""
    p = sub.add_parser("fmu", help="the physical drive as an FMI 2.0 co-simulation FMU (docs/fmu.md)")
    common(p, "FMU file to write (.fmu)")
    p.set_defaults(handler=lambda args: run(args, load))


def run(args: argparse.Namespace, load: Callable[[argparse.Namespace], Parameters]) -> int:
    from ..fmu.export import write_fmu  # numba and the C compiler: only for this subcommand

    params = load(args)
    write_fmu(params, Path(args.out))
    print(f"{args.out}: FMI 2.0 co-simulation FMU of the physical drive, {params.method} dt={params.time_step_s:g} s")
    return 0
