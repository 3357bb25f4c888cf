"""Whether a recorded run ran on one continuous time line, as boom-resim needs it.

boom-resim replays the recorded commands on one time line from the run's origin. A run
whose drive was reset (``~/reset``, or a ROS clock that jumped back) jumped in state, and
on ROS-time stamps a pause, a resume or a step moved the node's time origin: such runs
cannot be reproduced that way, and boom-resim refuses them rather than be wrong in silence.
This is for bags recorded before the node recorded its run events (bags.run_events): with
them, boom-resim reproduces such runs, and none of this is asked.

Two kinds of evidence:

- the service calls the node recorded as rosbag2 service introspection
  (``<node>/reset/_service_event`` and so on, one RESPONSE_SENT event per call), read
  with the mcap reader and rclpy's generated classes, so that they do not depend on how a
  reader parses service schemas;
- for bags recorded before the node recorded its calls, the drive states themselves:
  ``valve_loss_energy_j`` is dissipation counted from the start or the last reset, which
  only grows, so a drop of it is a reset, and so is a jump of ``rod_position_m`` no
  physics step could make. (``supply_energy_j`` is no such sign: oil pushed back into the
  supply, as when the boom bounces on its lower end stop, draws it down.)
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from ..errors import BagError
from .reading import mcap_files

SERVICE_EVENT_SUFFIX = "/_service_event"
#: service_msgs/msg/ServiceEventInfo.RESPONSE_SENT: the server's reply, with request and response
RESPONSE_SENT = 2
#: The node's services whose successful calls break the time line, with how a count reads.
SERVICES = {"reset": "reset", "pause": "paused or resumed", "step": "stepped"}
#: A drop of the valve's dissipated energy larger than this is a reset (J; it only grows
#: between resets, and this allows for the rounding of a recorded float).
ENERGY_DROP_J = 1e-3
#: A rod movement between two states beyond what their speeds and accelerations allow, with
#: this much to spare, is a jump (m).
POSITION_SLACK_M = 1e-3


@dataclass
class Calls:
    """The successful calls of the node's services recorded in a bag, by service."""

    counts: dict[str, int] = field(default_factory=dict)
    first_s: dict[str, float] = field(default_factory=dict)  # simulated time of the first, per service

    def total(self, services: Sequence[str] = tuple(SERVICES)) -> int:
        return sum(self.counts.get(s, 0) for s in services)


#: The node's service -> its type (the event type is '<type>_Event').
SERVICE_TYPES = {
    "reset": "boom_hydraulics_msgs/srv/Reset",
    "pause": "std_srvs/srv/SetBool",
    "step": "boom_hydraulics_msgs/srv/Step",
}


def _event_class(service: str) -> type:
    """The generated class of the service's introspection event (``Reset.Event``)."""
    package, kind, name = SERVICE_TYPES[service].split("/")
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name).Event
    except (ImportError, AttributeError):
        raise BagError(f"no {SERVICE_TYPES[service]} in this environment; is the workspace sourced?") from None


def service_name(topic: str) -> str | None:
    """'reset' for '/crane1/boom_sim/reset/_service_event', if it is one of the node's services."""
    if not topic.endswith(SERVICE_EVENT_SUFFIX):
        return None
    name = topic.removesuffix(SERVICE_EVENT_SUFFIX).rsplit("/", 1)[-1]
    return name if name in SERVICES else None


def recorded_calls(bag: Path, node: str | None, origin_ns: int) -> Calls:
    """The successful calls of ~/reset, ~/pause and ~/step that ``bag`` holds (of ``node``,
    the recording node's fully qualified name, where known)."""
    from rclpy.serialization import deserialize_message

    calls = Calls()
    for file in mcap_files(bag):
        try:
            with file.open("rb") as handle:
                reader = make_reader(handle)
                summary = reader.get_summary()
                channels = summary.channels.values() if summary else ()
                topics = [
                    c.topic
                    for c in channels
                    if service_name(c.topic) and (not node or c.topic.startswith(f"{node.rstrip('/')}/"))
                ]
                if not topics:
                    continue
                for _, channel, message in reader.iter_messages(topics=topics):
                    service = service_name(channel.topic)
                    event = deserialize_message(message.data, _event_class(service))
                    if event.info.event_type != RESPONSE_SENT or not event.response or not event.response[0].success:
                        continue
                    at_ns = event.info.stamp.sec * 1_000_000_000 + event.info.stamp.nanosec
                    calls.counts[service] = calls.counts.get(service, 0) + 1
                    calls.first_s.setdefault(service, (at_ns - origin_ns) * 1e-9)
        except (McapError, OSError, ValueError, TypeError) as exc:
            raise BagError(f"{file}: cannot read the recorded service calls ({exc})") from None
    return calls


def describe(calls: Calls, with_times: bool = True) -> str:
    """'reset 12 times (~/reset, first at t = 0.500 s) and paused or resumed once (~/pause, ...)'."""
    parts = []
    for service, verb in SERVICES.items():
        n = calls.counts.get(service, 0)
        if n:
            times = "once" if n == 1 else "twice" if n == 2 else f"{n} times"
            first = f", first at t = {calls.first_s[service]:.3f} s" if with_times and service in calls.first_s else ""
            parts.append(f"{verb} {times} (~/{service}{first})")
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
