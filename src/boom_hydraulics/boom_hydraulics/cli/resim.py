"""``boom-resim``: a recorded session's valve commands fed into the model again, "what if".

    boom-resim bags/20261122-044106_boom_sim --set piston_diameter_m=0.063 --set rod_diameter_m=0.036 \\
        --out bags/what_if_63mm
    boom-resim run.mcap --config config/default.yaml --set payload_mass_kg=150 --out bags/heavy

The arguments only; what a re-simulation does, and what it refuses, is told in
:mod:`boom_hydraulics.resim.resimulation`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from ..model import config
from ..programs import RaisingParser, run_main, summary
from ..resim.resimulation import resimulate


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-resim", description=summary(__doc__))
        parser.add_argument("bag", type=Path, help="bag folder or .mcap file recorded by boom_sim")
        parser.add_argument("--config", type=Path, help="params YAML replacing the recorded parameters")
        parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="change one parameter")
        parser.add_argument("--out", type=Path, required=True, help="new bag folder (must not exist)")
        args = parser.parse_args(argv)
        overrides = dict(config.parse_assignment(s) for s in args.set)
        folder, states = resimulate(args.bag, args.out, args.config, overrides)  # Ctrl-C, SIGTERM: nothing kept
        print(f"boom-resim: {states} drive states in {folder}")
        return 0

    return run_main("boom-resim", body)


if __name__ == "__main__":
    sys.exit(main())
