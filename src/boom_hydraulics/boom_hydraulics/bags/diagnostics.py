"""The node's /diagnostics (CDR), once a second and after each service call that changes the run.

Four statuses (five while recording, one more in physical mode): the drive (or the failure
that stopped it), the battery (its state of charge, warned below LOW_CHARGE), real time (lag,
clock error, dropped backlogs), the commands (received and not applied), the run (resets,
pauses, ~/step calls and the shift of the time origin: what boom-resim must know of a bag)
and the recording. Packed to CDR without rclpy: the node and ``boom-sim live``
publish and record the same array.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .encoding import message, stamp, to_cdr
from .energy import finite, ledger_now

DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
OK, WARN, ERROR = 0, 1, 2  # DiagnosticStatus levels
#: The battery's status warns below this state of charge.
LOW_CHARGE = 0.1


@dataclass
class CommandCounts:
    """Valve commands received, and those not applied, by why."""

    received: int = 0
    stale: int = 0  # older than command_timeout_s when received
    lost: int = 0  # dropped by the middleware before the node took them
    refused: int = 0  # the queue of future commands was full


@dataclass
class RunCounts:
    """Calls that change a run: boom-resim checks a bag's run events (bags.run_events) against these counts."""

    resets: int = 0  # ~/reset
    pauses: int = 0  # ~/pause with data: true
    step_calls: int = 0  # ~/step


def _status(name: str, level: int, text: str, **values: Any) -> Any:
    return message(
        "diagnostic_msgs/msg/DiagnosticStatus",
        level=level,
        name=f"boom_sim: {name}",
        message=text,
        hardware_id="boom_hydraulics",
        values=[message("diagnostic_msgs/msg/KeyValue", key=k, value=str(v)) for k, v in values.items()],
    )


def diagnostics(
    stamp_ns: int,
    sim: Any,
    failure: str | None,
    paused: bool,
    pacer: Any,
    rate_hz: float,
    real_time_factor: float,
    commands: CommandCounts,
    run: RunCounts,
    origin_shift_s: float,
    recording: tuple[str | None, str] | None,
) -> bytes:
    """The array at ``stamp_ns`` of the run of ``sim`` (a solve.simulation.Simulator) paced by
    ``pacer`` (a solve.pacing.Pacer); ``recording``: (its error or None, its folder) while
    recording. Reading the pacer's dropped backlogs resets their count."""
    status = []
    if failure:
        status.append(_status("simulation", ERROR, f"stopped: {failure}"))
    else:
        out = sim.outputs()
        # resting on an end stop is normal; cavitation, an open relief valve and a battery asked
        # for more than it can give (eq. D11) are not
        warnings = [name for name in ("cavitation", "relief_open", "battery_overloaded") if out.get(name)]
        notes = ["at_end_stop"] if out.get("at_end_stop") else []
        status.append(
            _status(
                "drive",
                WARN if warnings else OK,
                ", ".join(warnings + notes) or "ok",
                sim_time_s=f"{sim.t:.3f}",
                paused=paused,
                substeps_most=sim.most_substeps,
                energy_residual_j=f"{sim.energy_residual():.4g}",
            )
        )
        now = ledger_now(sim.params, sim.t, sim.y, sim.constants, sim.u)
        if now is not None and finite(now):  # physical mode: the battery's charge
            soc = now.state_of_charge
            level = ERROR if soc <= 0.0 else (WARN if soc < LOW_CHARGE else OK)
            status.append(
                _status(
                    "battery",
                    level,
                    "empty" if soc <= 0.0 else ("low" if soc < LOW_CHARGE else "ok"),
                    state_of_charge=f"{soc:.4f}",
                    battery_drawn_j=f"{now.energy_j['battery_drawn']:.6g}",
                    battery_returned_j=f"{now.energy_j['battery_returned']:.6g}",
                )
            )
    behind = pacer.lag_s > 2.0 / rate_hz
    status.append(
        _status(
            "real-time",
            WARN if (behind or pacer.late_ticks) else OK,
            "cannot keep up" if (behind or pacer.late_ticks) else "ok",
            lag_s=f"{pacer.lag_s:.4f}",
            clock_error_s=f"{pacer.clock_error_s:.6f}",
            dropped_backlogs=pacer.late_ticks,
            real_time_factor=real_time_factor,
        )
    )
    pacer.late_ticks = 0
    dropped = commands.stale + commands.lost + commands.refused
    status.append(
        _status(
            "commands",
            WARN if dropped else OK,
            "some commands were not applied" if dropped else "ok",
            received=commands.received,
            stale=commands.stale,  # older than command_timeout_s when received
            lost=commands.lost,  # dropped by the middleware before the node took them
            refused=commands.refused,  # the queue of future commands was full
        )
    )
    # what a re-simulation of the bag must know: boom-resim checks the bag's run events against these counts
    status.append(
        _status(
            "run",
            OK,
            "ok",
            resets=run.resets,
            pauses=run.pauses,
            step_calls=run.step_calls,
            clock_origin_shift_s=f"{origin_shift_s:.6f}",
        )
    )
    if recording is not None:
        error, folder = recording
        if error is not None:
            status.append(_status("recording", ERROR, f"stopped: {error}"))
        else:
            status.append(_status("recording", OK, "ok", folder=folder))
    return to_cdr(message(DIAGNOSTIC_ARRAY, header={"stamp": stamp(stamp_ns)}, status=status))
