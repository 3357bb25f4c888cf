"""The bag of a live run: what the node records, in a rosbag2 (MCAP) folder of the user's naming.

The node's topics (:data:`.channels.OUTLETS` but TF), its parameter changes on
/parameter_events, and every valve command as received, at its receive time, on the node's
topic and type; the run description the node stores (parameters, time origin, publish rate,
command timeout, the node's name), so boom-analyze and boom-resim take it as one of the
node's. Written as the node writes its bags, in place while it runs: a killed run leaves a
bag that ``boom-bag-recover`` finishes.
"""

from __future__ import annotations

from pathlib import Path

from ..bags.encoding import parameter_event_cdr
from ..bags.recording import BagRecorder, Topic, offered_qos, run_description
from ..model.parameters import Parameters
from .channels import NODE, bag_topics
from .steering import VALVE_TOPICS

PARAMETER_EVENTS = "/parameter_events"
PARAMETER_EVENTS_TYPE = "rcl_interfaces/msg/ParameterEvent"
PARAMETER_EVENTS_DEPTH = 1000  # rclpy's qos_profile_parameter_events


class LiveRecording:
    """The bag of one live run, opened at its time origin."""

    def __init__(self, folder: Path, params: Parameters, origin_ns: int, rate_hz: float, timeout_s: float) -> None:
        events = Topic(PARAMETER_EVENTS, PARAMETER_EVENTS_TYPE, (offered_qos(depth=PARAMETER_EVENTS_DEPTH),))
        topics = [*bag_topics(), events]
        custom = run_description(params, origin_ns, rate_hz, timeout_s, node=NODE)
        self.recorder = BagRecorder(folder, topics, custom_data=custom)
        self._reported = False

    def failed_now(self) -> str | None:
        """The error that stopped the recording (a full disk), the first time it is asked for
        after the disk failed; None before and after: the run says it once, at once, as the
        node does ("recording stopped: ...; the simulation goes on")."""
        if self._reported or self.recorder.error is None:
            return None
        self._reported = True
        return self.recorder.error

    def write(self, topic: str, log_ns: int, data: bytes) -> None:
        self.recorder.write(topic, log_ns, data)

    def command(self, topic: str, received_ns: int, data: bytes) -> None:
        """A valve command as received (the node's type for ``topic``), declared at its first."""
        if topic not in self.recorder.topics:
            self.recorder.add_topic(Topic(topic, VALVE_TOPICS[topic], (offered_qos(),)))
        self.recorder.write(topic, received_ns, data)

    def parameter_event(self, log_ns: int, changed_at_ns: int, changed: list) -> None:
        """A parameter change, stamped with the instant it took effect at (boom-resim applies it there)."""
        self.recorder.write(PARAMETER_EVENTS, log_ns, parameter_event_cdr(NODE, changed_at_ns, changed))

    def status(self) -> tuple[str | None, str]:
        """(the error that stopped the recording or None, the bag's folder), for the diagnostics."""
        return self.recorder.error, str(self.recorder.folder)

    def finish(self) -> tuple[Path, str, str | None]:
        """Finish the bag: (its folder, the messages per topic, the error that stopped it or None)."""
        folder = self.recorder.close()
        counts = ", ".join(f"{t} {n}" for t, n in self.recorder.counts.items() if n)
        return folder, counts, self.recorder.error
