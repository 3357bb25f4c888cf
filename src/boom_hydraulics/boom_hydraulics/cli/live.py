"""``boom-sim live``: the arguments of the live Foxglove server (the work: :mod:`..live.server`).

boom-sim live --config config/default.yaml                   # ws://127.0.0.1:8765, real time
boom-sim live --config config/default.yaml --record bags/live1 --rate 0.5
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..files import check_apart
from ..model import config

#: --rate's range: the node's real_time_factor (0: as fast as possible).
RATE_RANGE = (0.0, 1000.0)
#: --command-timeout-s's range: the node's command_timeout_s.
TIMEOUT_RANGE = (0.0, 3600.0)
#: --max-catch-up-s's range: the node's max_catch_up_s.
CATCH_UP_RANGE = (0.001, 10.0)


def _in_range(option: str, value: float, bounds: tuple[float, float]) -> float:
    low, high = bounds
    if not (math.isfinite(value) and low <= value <= high):
        raise ConfigError(f"{option} must be a number in [{low:g}, {high:g}], got {value!r}")
    return value


def cmd_live(args: argparse.Namespace) -> int:
    from ..live.server import serve  # foxglove-sdk: loaded by this subcommand only

    record = Path(args.record) if args.record else None
    if record is not None:
        check_apart(record, [args.config] if args.config else [])
    if not 0 <= args.port <= 65535:
        raise ConfigError(f"--port must be in [0, 65535] (0: any free port), got {args.port}")
    overrides: dict[str, Any] = dict(config.parse_assignment(s) for s in args.set)
    params = config.load(args.config, overrides) if args.config else config.from_overrides(overrides)
    return serve(
        params,
        host=args.host,
        port=args.port,
        real_time_factor=_in_range("--rate", args.rate, RATE_RANGE),
        command_timeout_s=_in_range("--command-timeout-s", args.command_timeout_s, TIMEOUT_RANGE),
        max_catch_up_s=_in_range("--max-catch-up-s", args.max_catch_up_s, CATCH_UP_RANGE),
        record=record,
    )


def add_parser(sub: Any) -> None:
    """``live`` under boom-sim's subcommands."""
    live = sub.add_parser(
        "live",
        help="a live run in Foxglove: a WebSocket server with the node's topics, steered by the client",
        description="Serve a live run to Foxglove (Open connection, Foxglove WebSocket, ws://HOST:PORT): the "
        "node's topics, the valve and a target angle from client-published channels, the model parameters "
        "through the protocol's parameters. Runs until Ctrl-C. docs/live.md tells the rest.",
    )
    live.add_argument("--config", help="ROS 2 params YAML (/**: ros__parameters: ...)")
    live.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override one parameter (repeatable)"
    )
    live.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine)")
    live.add_argument("--port", type=int, default=8765, help="port to listen on (default 8765; 0: any free port)")
    live.add_argument(
        "--rate",
        type=float,
        default=1.0,
        metavar="FACTOR",
        help="simulated seconds per wall second, the node's real_time_factor (default 1; 0: as fast as possible)",
    )
    live.add_argument(
        "--command-timeout-s",
        type=float,
        default=0.0,
        metavar="S",
        help="the valve closes when no command came for S simulated seconds (default 0: it holds the last one)",
    )
    live.add_argument(
        "--max-catch-up-s",
        type=float,
        default=0.2,
        metavar="S",
        help="the largest backlog a late tick works off; more is dropped, and boom-resim then refuses the bag "
        "(the node's max_catch_up_s; default 0.2)",
    )
    live.add_argument("--record", metavar="BAG", help="record the bag the node would into this new folder")
    live.set_defaults(handler=cmd_live)
