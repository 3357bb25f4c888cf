"""Recording serialized messages to a rosbag2 bag: a folder with ``metadata.yaml`` and one MCAP file.

The MCAP file follows the ``ros2`` profile as rosbag2 (Jazzy) writes it: schema encoding
``ros2msg`` with the full definition including nested types, message encoding ``cdr``,
channel metadata ``offered_qos_profiles`` (Jazzy's YAML) and ``topic_type_hash``
(RIHS01), zstd-compressed chunks with message indexes, and a statistics record. Writing
happens in a thread of its own behind a queue, so the caller never waits for the disk.

No rclpy here: the caller passes CDR bytes (``rclpy.serialization.serialize_message``).
"""

from __future__ import annotations

import json
import os
import queue
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import yaml
from mcap.writer import CompressionType, Writer
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from .errors import BoomHydraulicsError
from .parameters import Parameters, as_dict

ROSBAG2_VERSION = 9  # the metadata version rosbag2 writes in Jazzy
CUSTOM_DATA_RECORD = "boom_hydraulics"  # name of the MCAP metadata record with the custom data
_INFINITE = QosTime(sec=9223372036, nsec=854775807)


class RecordingError(BoomHydraulicsError):
    """A bag cannot be written (folder exists, unknown message type, disk error)."""


@dataclass(frozen=True)
class Topic:
    """One recorded topic: its resolved name, type and offered QoS."""

    name: str  # resolved, e.g. /drive_state
    msgtype: str  # e.g. boom_hydraulics_msgs/msg/DriveState
    reliable: bool = True
    depth: int = 10


def _share_dirs() -> list[Path]:
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [Path(p) / "share" for p in prefixes]


def _interface_file(msgtype: str, suffix: str) -> Path:
    package, kind, name = msgtype.split("/")
    for share in _share_dirs():
        candidate = share / package / kind / f"{name}{suffix}"
        if candidate.is_file():
            return candidate
    raise RecordingError(
        f"no {name}{suffix} of {msgtype} under AMENT_PREFIX_PATH; is the workspace sourced (tools/with-env)?"
    )


def type_hash(msgtype: str) -> str:
    """The RIHS01 type hash rosidl generated for ``msgtype`` (from its installed .json)."""
    description = json.loads(_interface_file(msgtype, ".json").read_text())
    for entry in description["type_hashes"]:
        if entry["type_name"] == msgtype:
            return entry["hash_string"]
    raise RecordingError(f"{msgtype}: no type hash in its type description")


def message_definition(msgtype: str) -> str:
    """The ros2msg definition of ``msgtype`` with every nested type, as rosbag2 stores it."""
    store = get_typestore(Stores.ROS2_JAZZY)
    if msgtype not in store.fielddefs:
        store.register(get_types_from_msg(_interface_file(msgtype, ".msg").read_text(), msgtype))
    text, _ = store.generate_msgdef(msgtype, ros_version=2)
    return text


def qos_profiles(topic: Topic) -> list[dict]:
    """Offered QoS of a publisher as rosbag2 (Jazzy, version 9) lists it in metadata.yaml."""
    qos = Qos(
        history=QosHistory.KEEP_LAST,
        depth=topic.depth,
        reliability=QosReliability.RELIABLE if topic.reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.VOLATILE,
        deadline=_INFINITE,
        lifespan=_INFINITE,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_INFINITE,
        avoid_ros_namespace_conventions=False,
    )
    return dump_qos_v9([qos])


def run_description(
    params: Parameters, clock_origin_ns: int, publish_rate_hz: float, command_timeout_s: float, **extra: str
) -> dict[str, str]:
    """The custom data a bag carries so that its run can be simulated again (boom-resim):
    the parameters, the stamp of simulated time 0, the publish rate and the command timeout."""
    return {
        "parameters": yaml.safe_dump(as_dict(params), sort_keys=False),
        "clock_origin_ns": str(clock_origin_ns),
        "publish_rate_hz": repr(publish_rate_hz),
        "command_timeout_s": repr(command_timeout_s),
        **extra,
    }


def new_bag_folder(parent: str | Path, name: str = "boom_sim") -> Path:
    """``parent/<UTC date-time>_<name>``: folders sort by start time."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    folder = Path(parent) / f"{stamp}_{name}"
    n = 1
    while folder.exists():  # two runs in the same second
        n += 1
        folder = Path(parent) / f"{stamp}-{n}_{name}"
    return folder


class BagRecorder:
    """Writes messages of known topics to a new bag folder; :meth:`close` finishes the bag."""

    def __init__(
        self,
        folder: str | Path,
        topics: list[Topic],
        chunk_size: int = 1 << 20,
        custom_data: dict[str, str] | None = None,
    ):
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            raise RecordingError(f"{self.folder}: a bag folder of that name exists already") from None
        except OSError as exc:
            raise RecordingError(f"{self.folder}: cannot create the bag folder ({exc.strerror})") from None
        self.file = self.folder / f"{self.folder.name}_0.mcap"
        self._stream = self.file.open("wb")
        self._writer = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="boom_hydraulics")
        # custom data (e.g. the run's parameters): in metadata.yaml and, so that a lone
        # .mcap file carries it too, as an MCAP metadata record
        self.custom_data = dict(custom_data or {})
        if self.custom_data:
            self._writer.add_metadata(CUSTOM_DATA_RECORD, self.custom_data)
        self.topics = {t.name: t for t in topics}
        self._channels: dict[str, int] = {}
        self.counts: dict[str, int] = {t.name: 0 for t in topics}
        schemas: dict[str, int] = {}
        for topic in topics:
            if topic.msgtype not in schemas:
                schemas[topic.msgtype] = self._writer.register_schema(
                    topic.msgtype, "ros2msg", message_definition(topic.msgtype).encode()
                )
            self._channels[topic.name] = self._writer.register_channel(
                topic.name,
                "cdr",
                schemas[topic.msgtype],
                {
                    # in the MCAP channel, the same list as a YAML string (as rosbag2 writes it)
                    "offered_qos_profiles": yaml.safe_dump(qos_profiles(topic), sort_keys=False),
                    "topic_type_hash": type_hash(topic.msgtype),
                },
            )
        self.first_ns: int | None = None
        self.last_ns = 0
        self.error: str | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._drain, name="bag_writer", daemon=True)
        self._thread.start()
        self._closed = False

    def write(self, topic: str, time_ns: int, data: bytes) -> None:
        """Queue one message (log time = publish time = ``time_ns``); returns at once."""
        if topic not in self._channels:
            raise RecordingError(f"{self.folder}: topic {topic} was not declared for this bag")
        self._queue.put((topic, time_ns, data))

    def _drain(self) -> None:
        while (item := self._queue.get()) is not None:
            topic, time_ns, data = item
            if self.error is not None:
                continue
            try:
                self._writer.add_message(self._channels[topic], time_ns, data, time_ns, self.counts[topic])
            except (OSError, ValueError) as exc:  # disk full, closed stream: keep what was written
                self.error = f"{self.file}: {exc}"
                continue
            self.counts[topic] += 1
            self.first_ns = time_ns if self.first_ns is None else min(self.first_ns, time_ns)
            self.last_ns = max(self.last_ns, time_ns)

    def close(self) -> Path:
        """Write out what is queued, finish the MCAP file and write metadata.yaml. Idempotent."""
        if self._closed:
            return self.folder
        self._closed = True
        self._queue.put(None)
        self._thread.join()
        self._writer.finish()
        self._stream.close()
        self._write_metadata()
        return self.folder

    def _write_metadata(self) -> None:
        write_metadata(
            self.folder,
            self.file.name,
            [
                (t.name, t.msgtype, qos_profiles(t), type_hash(t.msgtype), self.counts[t.name])
                for t in self.topics.values()
            ],
            self.first_ns or 0,
            self.last_ns,
            self.custom_data,
        )

    def __enter__(self) -> BagRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_metadata(
    folder: Path,
    file_name: str,
    topics: list[tuple[str, str, list[dict], str, int]],
    first_ns: int,
    last_ns: int,
    custom_data: dict[str, str],
) -> None:
    """rosbag2's metadata.yaml (version 9) for one MCAP file.

    ``topics``: (name, type, offered QoS list, type hash, message count) each.
    """
    duration = max(0, last_ns - first_ns)
    total = sum(t[4] for t in topics)
    info = {
        "version": ROSBAG2_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": first_ns},
        "message_count": total,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": name,
                    "type": msgtype,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": qos,
                    "type_description_hash": hash_,
                },
                "message_count": count,
            }
            for name, msgtype, qos, hash_, count in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [file_name],
        "files": [
            {
                "path": file_name,
                "starting_time": {"nanoseconds_since_epoch": first_ns},
                "duration": {"nanoseconds": duration},
                "message_count": total,
            }
        ],
        "custom_data": custom_data,
        "ros_distro": "jazzy",
    }
    tmp = folder / ".metadata.yaml.partial"
    tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))
    tmp.replace(folder / "metadata.yaml")
