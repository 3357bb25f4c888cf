"""``boom-analyze``: signals, metrics and plots of recorded runs.

    boom-analyze bags/20261122-043623_boom_sim
    boom-analyze run1/ run2/ --out out/compare      # runs overlaid in the plots

Per bag: <name>.csv (one column per signal, with units; time in s from the run's origin),
<name>.npz and <name>.metrics.json (strict JSON: a metric without a value is null); for
all bags together: dynamics.png (rod displacement, velocity, acceleration, piston-chamber
pressure: the panels of the paper's Figs. 8-10), drive.png (rod-chamber pressure, rod
force, valve) and, for bags that kept the node's energy ledger (~/energy, physical mode),
energy.png (where the battery's energy went, a bar per bag; the battery's figures join the
metrics). Only these files are written into the results folder, each whole or not at
all; nothing else in it is touched, and a folder that is or holds one of the bags is refused.

Runs are overlaid on a common time axis (--align): t = 0 at the recorded time origin, the
node's simulated time 0 (default; a boom-resim bag shares its source's origin), at the
first opening of the valve, or at each run's first message.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from ..analysis.recordings import analyze, default_results_folder, report
from ..bags.reading import ALIGNMENTS
from ..programs import RaisingParser, run_main, summary


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-analyze", description=summary(__doc__))
        parser.add_argument("bags", nargs="+", type=Path, help="bag folders or .mcap files")
        parser.add_argument("--out", type=Path, help="results folder (default: <first bag>.analysis next to it)")
        parser.add_argument(
            "--align",
            choices=ALIGNMENTS,
            default="origin",
            help="t = 0 at the recorded time origin (default), the first valve opening, or the first message",
        )
        args = parser.parse_args(argv)
        out = args.out or default_results_folder(args.bags[0])
        print(report(analyze(args.bags, out, args.align), out))
        return 0

    return run_main("boom-analyze", body)


if __name__ == "__main__":
    sys.exit(main())
