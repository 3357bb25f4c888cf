"""``boom-sim``: the boom drive without a ROS graph.

    boom-sim run --config config/default.yaml --duration 5 --out run.csv
    boom-sim run --config config/paper_fig8.yaml --duration 1.5 --method euler --dt 1e-4 --out e.csv
    boom-sim run --config config/default.yaml --profile steps:0=1,3=0,4=-1 --duration 7 --out cycle.csv
    boom-sim run --config config/default.yaml --target-angle-deg 30 --duration 4 --out move.csv
    boom-sim statics --config config/default.yaml --diameters 0.04,0.063,0.08 --out statics.csv
    boom-sim urdf --config config/default.yaml --out boom_crane.urdf
    boom-sim linearize --config config/default.yaml --rod-length-m 1.37 --controller --out linear
    boom-sim fmu --config config/default.yaml --out boom_drive.fmu

Errors in arguments, configs or the run print one line and exit non-zero.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import studies
from ..analysis.metrics import move_window
from ..errors import ConfigError
from ..files import atomic_path, check_apart, csv_rows, write_bytes, write_csv
from ..model import config
from ..model.parameters import METHODS, Parameters, from_mapping
from ..model.robot_description import JOINTS, urdf
from ..programs import RaisingParser, run_main
from ..solve import accelerate, commands, duty_cycles, outcomes
from ..solve.simulation import OUTPUTS, RunStream, check_fits, step_count
from . import fmu, linearize, live


def load_parameters(args: argparse.Namespace) -> Parameters:
    """Config file (or defaults) plus --set, --profile, --method and --dt, validated at once."""
    check_apart(Path(args.out), [args.config] if args.config else [])
    overrides: dict[str, Any] = dict(config.parse_assignment(s) for s in args.set)
    if getattr(args, "profile", None) and getattr(args, "target_angle_deg", None) is not None:
        raise ConfigError("give either --profile or --target-angle-deg, not both")
    profile = getattr(args, "profile", None)
    cycle = profile is not None and profile.partition(":")[0] in duty_cycles.CYCLES
    if profile and not cycle:
        overrides.update(commands.parse_profile(profile))
    if getattr(args, "target_angle_deg", None) is not None:
        if not math.isfinite(args.target_angle_deg):
            raise ConfigError(f"--target-angle-deg must be a finite angle in degrees, got {args.target_angle_deg}")
        overrides.update(commands.parse_profile(f"angle:0={args.target_angle_deg!r}", "--target-angle-deg"))
    if getattr(args, "method", None):
        overrides["method"] = args.method
    if getattr(args, "dt", None) is not None:
        overrides["time_step_s"] = args.dt
    params = config.load(args.config, overrides) if args.config else config.from_overrides(overrides)
    if cycle:  # a work cycle starts from the boom the parameters give
        params = from_mapping(commands.scenario(profile, 0.0, params), base=params)
    return params


def cmd_run(args: argparse.Namespace) -> int:
    params = load_parameters(args)
    step_count(params, args.duration, "--duration")  # a positive, finite duration a run can take
    if args.every < 1:
        raise ConfigError(f"--every must be >= 1, got {args.every}")
    if accelerate.not_in_cache(
        accelerate.run_kernels(params.mode, params.method, 1, accelerate.with_elements([params]))
    ):
        print(f"boom-sim: {accelerate.compiling_notice(params.mode, params.method, 'this run')}", file=sys.stderr)
    stream = RunStream(params, args.duration, commands.from_parameters(params), every=args.every)
    first_q1, last_q1, rows, start, overloaded = _stream_csv(Path(args.out), stream)
    print(
        f"{args.out}: {rows} rows, {params.mode} mode, {params.method} dt={params.time_step_s:g} s, "
        f"q1 {first_q1:.4f} -> {last_q1:.4f} m"
        + (
            f", up to {stream.most_substeps} substeps per step ({outcomes.substeps_cause(params.method)})"
            if stream.most_substeps > params.substeps
            else ""
        )
    )
    if params.command_profile == "angle":
        print(_move_summary(params, stream.metrics, start))
    if overloaded:
        print(
            f"boom-sim: warning: the battery could not give the power the drive asked in {overloaded} of the "
            f'{rows} rows (battery_overloaded; docs/model.md, "Battery"): its energy ledger does not close there; '
            "raise battery_voltage_v or lower battery_resistance_ohm",
            file=sys.stderr,
        )
    return 0


def _stream_csv(out: Path, stream: RunStream) -> tuple[float, float, int, float, int]:
    """Write the run's samples to ``out`` as they come (temporary name, renamed at the end:
    memory stays flat however long the run), with a progress bar on stderr when it is a
    terminal. Returns q1 at the start and the end, the rows written, the elevation at the
    first sample of the closed-loop move (NaN without one) and the rows in which the battery
    was overloaded."""
    from tqdm import tqdm

    start_s, end_s, _ = move_window(stream.params)
    first_q1, last_q1, rows, start_alpha, overloaded = math.nan, math.nan, 0, math.nan, 0
    progress = tqdm(total=stream.duration_s, unit="s", unit_scale=True, disable=None, file=sys.stderr,
                    desc="boom-sim", bar_format=PROGRESS_FORMAT)  # fmt: skip
    with progress, atomic_path(out) as tmp, tmp.open("w", newline="", encoding="utf-8") as handle:
        csv.writer(handle).writerow([f"{name} [{unit}]" for name, unit, _ in OUTPUTS])
        for chunk in stream:
            handle.write(csv_rows([chunk[name] for name, _, _ in OUTPUTS]))
            handle.flush()  # what is written can be seen growing, and the disk fills now, not at the end
            if rows == 0:
                first_q1 = float(chunk["q1"][0])
            if math.isnan(start_alpha):
                inside = np.nonzero((chunk["t"] >= start_s) & (chunk["t"] < end_s))[0]
                start_alpha = float(chunk["alpha"][inside[0]]) if len(inside) else math.nan
            last_q1 = float(chunk["q1"][-1])
            rows += len(chunk["t"])
            overloaded += int(np.count_nonzero(chunk["battery_overloaded"]))
            progress.update(stream.done_s - progress.n)
    return first_q1, last_q1, rows, start_alpha, overloaded


#: The progress bar: simulated seconds done of the run's, rate and time left.
PROGRESS_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n:.4g}/{total:.4g} s simulated [{elapsed}<{remaining}]"


def _move_summary(params: Parameters, m: dict[str, float], start_rad: float) -> str:
    """One line on the closed loop's first move (metrics ``m`` of the run's samples, elevation
    ``start_rad`` at the move's first sample): target, settling, overshoot, final error."""
    settle = m["settling_s"]
    start_s, end_s, target_rad = move_window(params)
    target = math.degrees(target_rad)
    if math.isnan(start_rad):  # no sample between the move's start and the next move's
        window = f"{start_s:g} s to {end_s:g} s" if math.isfinite(end_s) else f"from {start_s:g} s"
        return (
            f"closed loop: the move to {target:.2f} deg ({window}) has no sample to measure it by; sample more "
            "often (a smaller --every)"
        )
    return (
        f"closed loop: {math.degrees(start_rad):.2f} -> {target:.2f} deg, "
        + (f"settled within 2 % in {settle:.3f} s" if math.isfinite(settle) else "not settled within 2 %")
        + f", overshoot {m['target_overshoot_deg']:.3f} deg, final error {m['target_error_deg']:.3f} deg"
    )


#: Floats per position that boom-sim statics holds at its peak, besides one per diameter: the
#: table's columns, the geometry's intermediate arrays and the stacked copy for the CSV.
STATICS_WORK_COLUMNS = 16


def statics_table(params: Parameters, diameters_m: Sequence[float], points: int) -> tuple[list[str], np.ndarray]:
    """alpha, phi, static rod force and holding pressure over the open geometric stroke (Figs. 3-5)."""
    table = studies.statics(params, diameters_m, points)
    return studies.statics_header(table), np.column_stack(list(table.values()))


def cmd_statics(args: argparse.Namespace) -> int:
    params = load_parameters(args)
    try:
        diameters = [float(x) for x in args.diameters.split(",") if x]
    except ValueError:
        raise ConfigError(f"--diameters expects comma-separated metres, got {args.diameters!r}") from None
    if not diameters or any(not (d > 0 and math.isfinite(d)) for d in diameters):
        raise ConfigError(f"--diameters must be positive diameters in m, got {args.diameters!r}")
    if args.points < 2:
        raise ConfigError(f"--points must be >= 2, got {args.points}")
    check_fits(
        args.points * (len(diameters) + STATICS_WORK_COLUMNS),
        f"--points {args.points} with {len(diameters)} diameters",
        "ask for fewer points (a few thousand draw every curve smooth)",
    )
    header, table = statics_table(params, diameters, args.points)
    write_csv(Path(args.out), header, ([repr(float(v)) for v in row] for row in table))
    print(f"{args.out}: {len(table)} positions x {len(diameters)} piston diameters")
    return 0


def cmd_urdf(args: argparse.Namespace) -> int:
    params = load_parameters(args)
    write_bytes(Path(args.out), urdf(params).encode())
    print(f"{args.out}: URDF of the crane ({', '.join(JOINTS)}) with the config's dimensions")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = RaisingParser(prog="boom-sim", description="Simulate the crane boom's hydraulic drive without ROS.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=RaisingParser)

    def common(p: argparse.ArgumentParser, out_help: str = "CSV file to write") -> None:
        p.add_argument("--config", help="ROS 2 params YAML (/**: ros__parameters: ...)")
        p.add_argument(
            "--set",
            action="append",
            default=[],
            metavar="KEY=VALUE",
            help="override one parameter (repeatable), e.g. --set piston_diameter_m=0.063",
        )
        p.add_argument("--out", required=True, help=out_help)

    run = sub.add_parser("run", help="integrate over time and write one CSV row per step")
    common(run)
    run.add_argument("--duration", type=float, required=True, help="simulated seconds")
    run.add_argument("--method", choices=METHODS, help="integrator (default: config)")
    run.add_argument("--dt", type=float, help="time step in s (default: config)")
    run.add_argument("--every", type=int, default=1, help="write every N-th step (default 1)")
    run.add_argument(
        "--profile",
        help="valve command: constant:U | steps:T=U,... | ramp:T=U,... | sine:OFFSET,AMPLITUDE,FREQ_HZ, or "
        "closed loop: angle:T=DEG,... (at time T, move the boom to DEG degrees), or a work cycle: loader "
        "(18.5 s; loader:SEED as an operator varies it)",
    )
    run.add_argument(
        "--target-angle-deg",
        type=float,
        metavar="DEG",
        help="closed loop: move the boom to DEG degrees at control_max_speed_rad_s and hold it "
        "(the same as --profile angle:0=DEG)",
    )
    run.set_defaults(handler=cmd_run)

    statics = sub.add_parser("statics", help="alpha, phi, static force and holding pressure over the stroke")
    common(statics)
    statics.add_argument("--diameters", default="0.04,0.063,0.08", help="piston diameters in m")
    statics.add_argument("--points", type=int, default=161, help="positions over the stroke")
    statics.set_defaults(handler=cmd_statics)

    description = sub.add_parser("urdf", help="the crane's URDF (as the node publishes it on robot_description)")
    common(description, "URDF file to write")
    description.set_defaults(handler=cmd_urdf)

    linearize.register(sub, common, load_parameters)  # boom-sim linearize (cli/linearize.py)
    live.add_parser(sub)  # boom-sim live (cli/live.py)
    fmu.register(sub, common, load_parameters)  # boom-sim fmu (cli/fmu.py)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        args = build_parser().parse_args(argv)
        return args.handler(args)

    return run_main("boom-sim", body)


if __name__ == "__main__":
    sys.exit(main())
