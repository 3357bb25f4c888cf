"""Valve commands as the node takes them: ``valve_command`` (stamped) and ``commands`` (one value, now).

Each command is recorded as received (raw bytes), then parsed once. Its opening is clamped to
the mode's range (a non-finite one is ignored); a stamped command acts at its stamp, mapped
to simulated time by the node's clock (a zero stamp: now), unless it is older than
``command_timeout_s`` when it arrives (stale). The drive's queue of future commands is bounded
(refused beyond it). Commands a lone publisher sent that never arrived (Fast DDS raises no
message-lost event; the sensor-data queue keeps the last 5) are counted from the gaps in its
sequence numbers. The counts go to /diagnostics.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64MultiArray

from boom_hydraulics_msgs.msg import ValveCommand

from ..bags import cdr
from ..bags.diagnostics import CommandCounts
from ..solve.command_queue import CommandedDrive, stale, valve_opening
from .clock import NodeClock


def read_valve_command(data: bytes) -> tuple[Any, float]:
    """The stamp (with ``sec`` and ``nanosec``) and the opening of a ValveCommand received as
    CDR bytes: read straight from them (no message object: the executor's time a command),
    or by rclpy where they are in another encoding."""
    read = cdr.valve_command(data)
    if read is None:
        msg = deserialize_message(data, ValveCommand)
        return msg.header.stamp, msg.opening
    return read


class CommandIntake:
    """The two command topics of one node (callers hold the node's lock)."""

    def __init__(
        self,
        topics: dict[str, Any],
        drive: CommandedDrive,
        clock: NodeClock,
        logger: RcutilsLogger,
        record: Callable[[str, bytes, dict], None],
    ) -> None:
        self.topics = topics  # resolved name -> message type: valve_command, commands
        self.valve_topic, self.array_topic = topics
        self.drive, self.clock, self.logger, self.record = drive, clock, logger, record
        self.counts = CommandCounts()
        self._sole_publisher = dict.fromkeys(topics, False)
        self._last_sequence: dict[str, int] = {}

    def on_valve_command(self, data: bytes, info: dict) -> None:
        self.record(self.valve_topic, data, info)
        self._count_lost(self.valve_topic, info)
        stamp, opening = read_valve_command(data)
        self._accept(opening, stamp)

    def on_command_array(self, data: bytes, info: dict) -> None:
        self.record(self.array_topic, data, info)
        self._count_lost(self.array_topic, info)
        msg = deserialize_message(data, Float64MultiArray)
        if len(msg.data) != 1:
            self.logger.warning(
                f"'commands' expects one value (the valve opening), got {len(msg.data)}", throttle_duration_sec=1.0
            )
            return
        self._accept(msg.data[0], None)

    def _accept(self, opening: float, stamp: Any | None) -> None:
        drive, counts = self.drive, self.counts
        u = valve_opening(opening, drive.sim.params.mode)
        if u is None:
            self.logger.warning(f"ignored non-finite valve opening {opening}", throttle_duration_sec=1.0)
            return
        if u != opening:
            self.logger.warning(f"valve opening {opening} clamped to {u:g}", throttle_duration_sec=1.0)
        counts.received += 1
        at = self.clock.stamp_to_sim_time(stamp) if stamp is not None else None
        if at is not None:
            received_s = self.clock.received_s()  # by the log time the bag keeps
            if stale(at, received_s, drive.timeout_s):
                counts.stale += 1
                self.logger.warning(
                    f"ignored a valve command stamped {received_s - at:.3f} s before it arrived: older than "
                    f"command_timeout_s = {drive.timeout_s:g} s, it is stale; stamp commands with the time they are "
                    "meant for (a zero stamp: now), or raise command_timeout_s",
                    throttle_duration_sec=1.0,
                )
                return
        if not drive.push(drive.sim.t if at is None else at, u):
            counts.refused += 1
            self.logger.warning("too many future-stamped commands waiting; refused", throttle_duration_sec=1.0)

    def _count_lost(self, topic: str, info: dict) -> None:
        """Count the commands a lone publisher sent that never reached this node."""
        sequence = info.get("publication_sequence_number")
        if not sequence or not self._sole_publisher[topic]:
            return
        last = self._last_sequence.get(topic)
        if last is not None and sequence > last + 1:
            self.counts.lost += sequence - last - 1
        self._last_sequence[topic] = sequence

    def watch_publishers(self, publishers: Mapping[str, Sequence[Any]]) -> None:
        """Once a second, with the publishers that reach each command topic: which topics have
        one (whose gaps are losses)."""
        for topic in self.topics:
            sole = len(publishers.get(topic, ())) == 1
            if sole != self._sole_publisher[topic]:
                self._sole_publisher[topic] = sole
                self._last_sequence.pop(topic, None)
