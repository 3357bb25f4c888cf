"""``boom-sweep``: which cylinder? A design sweep over any parameters, with a recommendation.

    boom-sweep --config config/default.yaml --vary piston_diameter=0.032:0.1:15 \\
        --vary payload=0:200:5 --scenario lift --out sweeps/diameter --across payload \\
        --max-pressure-pa 18e6 --max-lift-time-s 2.5 --no-cavitation

Every point runs the same valve scenario; the points are integrated together in
batches (numpy-vectorised), in this process, on local worker processes (``--workers``)
or on a Dask cluster (``--scheduler``), with identical results. OUT receives:

- ``results.csv`` / ``results.npz``: one row per point: its parameters, ``status``
  (ok, incomplete, failed, invalid), ``reason``, the design metrics and ``front``
  (1 on the trade-off front of lift time, lift energy and peak pressure);
- ``metrics_vs_<parameter>.png`` and ``trade_off.png``;
- with ``--recommend`` or a constraint: ``recommendation.txt`` and the recommended rows
  ranked, as ``recommendation.csv`` / ``.npz`` (with ``--across payload``: one row per
  cylinder, worst case over the payloads);
- ``sweep.json`` and ``batches/``: what was asked and each finished batch, so that an
  interrupted sweep finishes with ``--resume`` without redoing them.

OUT may hold other files (``--out .``): the sweep writes only the names above there, and refuses
a folder where one of them exists without a ``sweep.json``. Every failure ends in one line,
``boom-sweep: error: ...``: bad arguments, configs or numbers, a folder holding another sweep or
a batch file that is not this sweep's exit 2; a damaged ``sweep.json``, a failing point set on a
cluster or a disk error exit 1; Ctrl-C exits 130 and SIGTERM 143, keeping every finished batch
and naming the command that finishes the sweep. The size (points, batches, steps and a time
at a nominal rate) is said before planning a large sweep, and one that cannot fit in memory is
refused before anything is planned. Where the run kernel is not in numba's cache yet (``make
setup`` puts the configuration's there), a line says that the first batch compiles it.
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

from ..errors import BoomHydraulicsError, ConfigError
from ..programs import DefaultsFormatter, RaisingParser, Terminated, run_main, stop_received, stop_words
from ..sweeps import sweep
from ..sweeps.recommend import RANKINGS
from ..sweeps.rules import TARGET_TOLERANCE_DEG
from ..sweeps.runner import BATCH_SIZE, Reached, SweepOptions, run_sweep
from ..sweeps.sampling import SAMPLES


def build_parser() -> argparse.ArgumentParser:
    parser = RaisingParser(
        prog="boom-sweep",
        description="Sweep cylinder designs through one valve scenario and rank them.",
        formatter_class=DefaultsFormatter,
    )
    what = parser.add_argument_group("what to sweep")
    what.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="FILE",
        help="ROS 2 params YAML; repeat to sweep across configs (default: the built-in values)",
    )
    what.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a parameter")
    what.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="NAME=SPEC",
        help="START:STOP:COUNT, START:STOP:COUNT:log, V1,V2,... or LOW:HIGH (random/lhs); repeatable",
    )
    what.add_argument("--sample", choices=SAMPLES, default="grid", help="how the axes combine")
    what.add_argument("--samples", type=int, default=0, metavar="N", help="points of a random/lhs sample")
    what.add_argument("--seed", type=int, default=0, help="seed of a random/lhs sample")
    how = parser.add_argument_group("the scenario and its metrics")
    how.add_argument(
        "--scenario",
        default="lift",
        help="lift (open for half the run, then hold), lift:T, cycle, loader (a loader crane's work cycle: "
        "lift the payload, lower it, release it, lift and lower empty; 18.5 s), config, a profile such as "
        "steps:0=1,2=0, or a closed-loop move such as angle:0=30 (lift to 30 degrees under position control and hold)",
    )
    how.add_argument(
        "--operators",
        type=int,
        default=0,
        metavar="N",
        help="run each design through N cycles of the loader scenario as operators vary it (seeds 1 to N: "
        "phase lengths within 20 %%, lift heights within 10 %%); the table gains the column operator, and "
        "operators.csv each design's 10th-90th percentile band",
    )
    how.add_argument("--duration", type=float, default=5.0, help="simulated seconds per point")
    how.add_argument("--lift-angle-deg", type=float, default=20.0, help="boom rise that completes a lift")
    how.add_argument("--every", type=int, default=1, help="sample the signals every N steps for the metrics")
    run = parser.add_argument_group("where it runs")
    run.add_argument(
        "--batch-size",
        type=int,
        metavar="N",
        help=f"points integrated together (default {BATCH_SIZE}, or fewer to give each of --workers a share; "
        "about 0.37 GB per 1000 points of a 5 s run)",
    )
    where = run.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://host:8786")
    where.add_argument("--workers", type=int, metavar="N", help="start a local Dask cluster of N processes")
    run.add_argument(
        "--scheduler-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds to wait for the --scheduler to answer (default 10)",
    )
    run.add_argument("--out", type=Path, help="output folder (default: sweeps/sweep-DATE-TIME)")
    run.add_argument("--resume", action="store_true", help="finish the sweep begun in --out")
    run.add_argument("--no-plots", action="store_true", help="write tables only")
    run.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress bar on stderr (default: when stderr is a terminal)",
    )
    pick = parser.add_argument_group("recommendation")
    pick.add_argument(
        "--recommend",
        action="store_true",
        help="rank the designs that meet the rules (below: a closed-loop run's targets, set-down and port reliefs, "
        "--max-pressure-pa) and the constraints",
    )
    pick.add_argument(
        "--max-pressure-pa",
        type=float,
        help="rule: peak_pressure_pa <= VALUE (the recommendation and every summary line)",
    )
    pick.add_argument("--max-lift-time-s", type=float, help="constraint: lift_time_s <= VALUE")
    pick.add_argument("--no-cavitation", action="store_true", help="constraint: cavitation_s == 0")
    pick.add_argument(
        "--target-tolerance-deg",
        type=float,
        default=TARGET_TOLERANCE_DEG,
        metavar="DEG",
        help="rule of a closed-loop scenario (angle:, loader): the boom within DEG of each target at the end of "
        "its phase (the next target's time; the last one's at the end of the run)",
    )
    pick.add_argument(
        "--set-down-tolerance-deg",
        type=float,
        metavar="DEG",
        help="rule of a work cycle: the boom within DEG of the ground when the payload is released "
        "(default: --target-tolerance-deg)",
    )
    pick.add_argument(
        "--settle-time-s",
        type=float,
        metavar="S",
        help="rule of a closed-loop scenario: each target reached (within 2 %% of its step) and held from at most "
        "S after its phase's start (default: no such rule)",
    )
    pick.add_argument(
        "--allow-relief",
        action="store_true",
        help="recommend designs whose port relief valves open (default: a design qualifies only if none opens)",
    )
    pick.add_argument("--require", action="append", default=[], metavar="EXPR", help="e.g. 'damping_ratio>=0.1'")
    pick.add_argument(
        "--across",
        action="append",
        default=[],
        metavar="NAME",
        help="a varied parameter that is a condition, not a design choice (e.g. payload): a design must "
        "meet the constraints at all its values and is ranked by its worst case",
    )
    pick.add_argument(
        "--rank-by",
        choices=tuple(RANKINGS),
        help="rank the designs that meet the constraints by this (cycles_per_charge: most first, the others "
        "least; default lift_energy_j)",
    )
    pick.add_argument("--top", type=int, default=10, help="designs shown in the recommendation")
    return parser


def _resume_command(argv: Sequence[str], out: Path, args: argparse.Namespace) -> str:
    """The command that finishes the sweep, as the user can type it where they are: through the
    checkout's tools/with-env where it ran through it (its environment says so), relative to
    the current folder where it is the checkout's."""
    words = ["boom-sweep", *argv]
    launcher = os.environ.get("BOOM_HYDRAULICS_WITH_ENV")
    if launcher:
        here = Path("tools/with-env")
        same = here.exists() and here.resolve() == Path(launcher).resolve()
        words.insert(0, str(here) if same else launcher)
    if args.out is None:
        words += ["--out", str(out)]
    if not args.resume:
        words.append("--resume")
    return shlex.join(words)


def check_numbers(args: argparse.Namespace) -> None:
    """Refuse, in one line, numbers that make no sense, before anything is read or planned."""
    numbers = ("duration", "lift_angle_deg", "max_pressure_pa", "max_lift_time_s", "scheduler_timeout",
               "target_tolerance_deg", "set_down_tolerance_deg", "settle_time_s")  # fmt: skip
    for name in numbers:
        value = getattr(args, name)
        if value is not None and not math.isfinite(value):
            raise ConfigError(f"--{name.replace('_', '-')} must be a finite number, got {value}")
    sweep.check_duration(args.duration)
    for name in ("target_tolerance_deg", "set_down_tolerance_deg", "settle_time_s"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise ConfigError(f"--{name.replace('_', '-')} must be > 0, got {value}")
    if not args.scheduler_timeout > 0:
        raise ConfigError(f"--scheduler-timeout must be > 0 s, got {args.scheduler_timeout}")
    for name, least in (("samples", 0), ("seed", 0), ("every", 1), ("batch_size", 1), ("workers", 1), ("top", 1)):
        value = getattr(args, name)
        if value is not None and value < least:
            raise ConfigError(f"--{name.replace('_', '-')} must be a whole number >= {least}, got {value}")
    cores = os.cpu_count() or 1
    if args.workers is not None and args.workers > cores:
        raise ConfigError(
            f"--workers {args.workers}: this machine has {cores} cores, and each worker process runs on a share "
            "of them; give at most that many, or --scheduler to use a larger cluster"
        )


def run(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """The sweep; Ctrl-C (exit 130) or SIGTERM (143, see run_main) at any moment ends it with one line
    saying what is stored and the command that finishes it; a batch being written is not kept."""
    reached = Reached()

    def finish(out: Path) -> str:
        return _resume_command(argv, out, args)

    try:
        check_numbers(args)
        return run_sweep(SweepOptions(**vars(args)), reached)
    except KeyboardInterrupt as stop:  # (Terminated, SIGTERM's, is one)
        signum = signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT
    except (BoomHydraulicsError, OSError):  # their own one line (run_main), signal or not
        raise
    except Exception:
        signum = stop_received()  # a signal's exception that the code it landed in made another
        if signum is None:
            raise
    print(reached.interrupted(stop_words(signum), finish), file=sys.stderr)
    return 128 + signum


def main(argv: Sequence[str] | None = None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)

    def body() -> int:
        return run(build_parser().parse_args(words), words)

    return run_main("boom-sweep", body)


if __name__ == "__main__":
    sys.exit(main())
