"""Entry point of ``boom_sim``: a Ctrl-C while the node's modules load (rclpy, numba, about
1.5 s) ends in one line, as it does once the node runs (see :mod:`.process`)."""

from __future__ import annotations

import sys


def main() -> None:
    try:
        from .process import main as node_main
    except KeyboardInterrupt:
        print("boom_sim: stopped while starting; nothing was recorded", file=sys.stderr, flush=True)
        return
    node_main()


if __name__ == "__main__":
    main()
