"""``boom-bag-recover``: finish a bag whose recorder was killed (SIGKILL, power loss) or whose disk failed.

    boom-bag-recover bags/20261122-044106_boom_sim

Every complete chunk that reached the disk comes back, in a finished MCAP file under the
original name with metadata.yaml; the damaged file stays beside it as <name>.damaged (and
a metadata.yaml that stood beside a cut file, as metadata.yaml.damaged). A whole file of
the node's whose metadata.yaml is missing gets one, and is not changed. The result is whole
or nothing: on a full disk nothing changes, and after an interruption a rerun continues. A
bag whose recorder is still running, a whole MCAP file of another tool, a file that is not
a rosbag2 recording, and a finished bag are refused, and nothing is changed. See
:mod:`..bags.recovery`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from ..bags.recovery import Recovery, recover
from ..programs import RaisingParser, run_main, summary


def report(result: Recovery) -> str:
    """What the user reads: what was kept, what was lost and what was cleaned up."""
    lines = []
    if result.removed:
        names = ", ".join(p.name for p in result.removed)
        lines.append(f"boom-bag-recover: removed {len(result.removed)} leftover(s) of an interrupted run: {names}")
    if result.resumed:
        lines.append(f"boom-bag-recover: an earlier run was interrupted; recovered again from {result.damaged.name}")
    lost = []
    if result.dropped_chunks:
        lost.append(f"{result.dropped_chunks} damaged chunk(s) dropped")
    if result.orphans:
        lost.append(f"{result.orphans} message(s) of a lost channel dropped")
    tail = f"; {', '.join(lost)}" if lost else ""
    if result.damaged is None:
        lines.append(
            f"boom-bag-recover: {result.file} was whole (its recorder was killed before writing metadata.yaml): "
            f"wrote metadata.yaml for its {result.messages} messages, the file is unchanged{tail}"
        )
        return "\n".join(lines)
    kept = (
        result.damaged.name
        if result.old_metadata is None
        else f"{result.damaged.name}, its old metadata.yaml {result.old_metadata.name}"
    )
    lines.append(
        f"boom-bag-recover: {result.messages} messages kept in {result.file} (the damaged file is {kept}){tail}"
    )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-bag-recover", description=summary(__doc__))
        parser.add_argument("bag", type=Path, help="the bag folder of a killed or failed recording")
        args = parser.parse_args(argv)
        print(report(recover(args.bag)))
        return 0

    return run_main("boom-bag-recover", body)


if __name__ == "__main__":
    sys.exit(main())
