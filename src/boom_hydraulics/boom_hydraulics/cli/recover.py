"""``boom-bag-recover``: finish a bag whose recorder was killed (SIGKILL, power loss).

    boom-bag-recover bags/20261122-044106_boom_sim

Every message that reached the disk comes back, in a finished MCAP file under the
original name with metadata.yaml; the damaged file stays beside it as <name>.damaged. A
bag whose recorder is still running is refused. See :mod:`..bags.recovery`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from ..bags.recovery import recover
from .common import RaisingParser, run_main, summary


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-bag-recover", description=summary(__doc__))
        parser.add_argument("bag", type=Path, help="the bag folder of a killed recording")
        args = parser.parse_args(argv)
        file, count = recover(args.bag)
        print(f"boom-bag-recover: {count} messages kept in {file} (the damaged file is {file.name}.damaged)")
        return 0

    return run_main("boom-bag-recover", body)


if __name__ == "__main__":
    sys.exit(main())
