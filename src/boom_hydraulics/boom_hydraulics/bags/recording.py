"""Recording serialized messages to a rosbag2 bag: a folder with ``metadata.yaml`` and one MCAP file.

The MCAP file follows the ``ros2`` profile as rosbag2 (Jazzy) writes it: schema encoding
``ros2msg`` with the ``.msg`` texts of the type and its nested types, comments included;
message encoding ``cdr``; channel metadata ``offered_qos_profiles`` (Jazzy's YAML) and
``topic_type_hash`` (RIHS01); zstd-compressed chunks with message indexes; a statistics
record; and a ``rosbag2`` metadata record with ``serialized_metadata`` (the bag's
metadata, distro and custom data), so that a ``.mcap`` copied out of its folder keeps them.

Safety of the data:

- Log time never decreases within a channel (the MCAP rule): a time earlier than the
  channel's last one is logged at that last time.
- The header and the custom data reach the disk at once; the first chunk is written as
  soon as the first messages arrive, and then a chunk is closed when it is full or when
  it is ``flush_s`` old, whichever comes first. A SIGKILL therefore loses at most
  ``flush_s`` seconds or one chunk of messages; ``boom-bag-recover`` finishes the rest.
- While recording, the recorder holds an exclusive lock (``flock``) on the MCAP file. The
  operating system frees it when the process dies, so :func:`is_being_recorded` tells a
  live bag from a killed one.

Writing happens in a thread of its own behind a queue, so the caller never waits for the
disk. No rclpy here: the caller passes CDR bytes.
"""

from __future__ import annotations

import fcntl
import json
import os
import queue
import re
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2.metadata import dump_qos_v9

from ..errors import RecordingError
from ..files import atomic_path
from ..model.parameters import Parameters, as_dict

ROSBAG2_VERSION = 9  # the metadata version rosbag2 writes in Jazzy
ROS_DISTRO = "jazzy"
CUSTOM_DATA_RECORD = "boom_hydraulics"  # name of the MCAP metadata record with the custom data
ROSBAG2_RECORD = "rosbag2"  # name of the MCAP metadata record rosbag2_storage_mcap writes
MCAP_MAGIC = b"\x89MCAP0\r\n"
_INFINITE = QosTime(sec=9223372036, nsec=854775807)
_DEFAULT_DEPTH = 10


def offered_qos(reliable: bool = True, transient_local: bool = False, depth: int = _DEFAULT_DEPTH) -> Qos:
    """One publisher's QoS offer as rosbag2 records it."""
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=depth,
        reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        deadline=_INFINITE,
        lifespan=_INFINITE,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_INFINITE,
        avoid_ros_namespace_conventions=False,
    )


@dataclass(frozen=True)
class Topic:
    """One recorded topic: its resolved name, type, and what its publishers offered."""

    name: str  # resolved, e.g. /drive_state
    msgtype: str  # e.g. boom_hydraulics_msgs/msg/DriveState
    offers: tuple[Qos, ...] = field(default_factory=lambda: (offered_qos(),))

    def qos_profiles(self) -> list[dict]:
        """The offers as rosbag2 (Jazzy, version 9) lists them in metadata.yaml."""
        return dump_qos_v9(list(self.offers))


# --- interface files --------------------------------------------------------------------
def _share_dirs() -> list[Path]:
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [Path(p) / "share" for p in prefixes]


def interface_file(msgtype: str, suffix: str) -> Path:
    package, *_, name = msgtype.split("/")
    for share in _share_dirs():
        candidate = share / package / "msg" / f"{name}{suffix}"
        if candidate.is_file():
            return candidate
    raise RecordingError(
        f"no {name}{suffix} of {msgtype} under AMENT_PREFIX_PATH; is the workspace sourced (tools/with-env)?"
    )


def type_hash(msgtype: str) -> str:
    """The RIHS01 type hash rosidl generated for ``msgtype`` (from its installed .json)."""
    description = json.loads(interface_file(msgtype, ".json").read_text())
    for entry in description["type_hashes"]:
        if entry["type_name"] == msgtype:
            return entry["hash_string"]
    raise RecordingError(f"{msgtype}: no type hash in its type description")


# rosbag2_cpp's LocalMessageDefinitionSource: the field types of a .msg text, and the
# delimiter between concatenated definitions.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string".split()
)
_DELIMITER = "=" * 80 + "\n"


def message_definition(msgtype: str) -> str:
    """The ros2msg definition of ``msgtype`` as rosbag2 stores it: the ``.msg`` text with its
    comments, then each nested type's text after a ``MSG: pkg/Type`` delimiter."""
    seen: set[str] = set()

    def full_text(name: str) -> str:
        package = name.split("/")[0]
        text = interface_file(name, ".msg").read_text()
        dependencies = set()
        for match in _FIELD_TYPE.finditer(text):
            kind = match.group(1)
            if kind not in _PRIMITIVES:
                dependencies.add(kind if "/" in kind else f"{package}/{kind}")
        for dependency in sorted(dependencies):
            if dependency not in seen:
                seen.add(dependency)
                text += f"\n{_DELIMITER}MSG: {dependency}\n{full_text(dependency)}"
        return text

    return full_text(msgtype)


# --- bag folders ------------------------------------------------------------------------
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
    """``parent/<UTC date-time>_<name>``: folders sort by start time. ``name`` is the node's
    fully qualified name (``/crane1/boom_sim`` gives ``crane1_boom_sim``)."""
    label = name.strip("/").replace("/", "_") or "boom_sim"
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    folder = Path(parent) / f"{stamp}_{label}"
    n = 1
    while folder.exists():  # two runs in the same second
        n += 1
        folder = Path(parent) / f"{stamp}-{n}_{label}"
    return folder


def is_being_recorded(mcap_file: Path) -> bool:
    """True while a live recorder holds the lock on ``mcap_file``."""
    try:
        with mcap_file.open("rb") as handle:
            try:
                fcntl.flock(handle.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return True
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
    except OSError:
        return False
    return False


def bag_info(
    file_name: str,
    topics: list[tuple[str, str, list[dict], str, int]],
    first_ns: int,
    last_ns: int,
    custom_data: dict[str, str],
) -> dict[str, Any]:
    """rosbag2's bag metadata (version 9) for one MCAP file.

    ``topics``: (name, type, offered QoS profiles, type hash, message count) each.
    """
    duration = max(0, last_ns - first_ns)
    total = sum(t[4] for t in topics)
    return {
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
        "ros_distro": ROS_DISTRO,
    }


def rosbag2_record(info: dict[str, Any]) -> dict[str, str]:
    """The ``rosbag2`` MCAP metadata record of a bag, as rosbag2_storage_mcap writes it."""
    return {"serialized_metadata": yaml.safe_dump(info, sort_keys=False)}


def write_metadata(folder: Path, info: dict[str, Any]) -> None:
    """``folder/metadata.yaml`` of ``info`` (see :func:`bag_info`), written whole."""
    with atomic_path(folder / "metadata.yaml") as tmp:
        tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))


_FLUSH_NOW = object()  # the writer's own signal, on a queue timeout: close the chunk in progress


class BagRecorder:
    """Writes messages to a new bag folder; :meth:`close` finishes the bag.

    Topics are declared at start or later with :meth:`add_topic` (a command topic, once
    its first publisher shows up); :meth:`add_offers` adds what a topic's new publishers
    offered, for the metadata written at close.
    """

    def __init__(
        self,
        folder: str | Path,
        topics: list[Topic],
        chunk_size: int = 1 << 20,
        custom_data: dict[str, str] | None = None,
        flush_s: float = 1.0,
        file_stem: str | None = None,
    ):
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            raise RecordingError(f"{self.folder}: a folder of that name exists already; name a new one") from None
        except OSError as exc:
            raise RecordingError(f"{self.folder}: cannot create the bag folder ({exc.strerror})") from None
        self.file = self.folder / f"{file_stem or self.folder.name}_0.mcap"
        self._stream = self.file.open("wb")
        fcntl.flock(self._stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)  # live until closed or dead
        self._writer = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="boom_hydraulics")
        # custom data (e.g. the run's parameters): in metadata.yaml and, so that a lone
        # .mcap file carries it too, as an MCAP metadata record at once
        self.custom_data = dict(custom_data or {})
        if self.custom_data:
            self._writer.add_metadata(CUSTOM_DATA_RECORD, self.custom_data)
        self._stream.flush()
        self.flush_s = flush_s
        self.topics: dict[str, Topic] = {}
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._hashes: dict[str, str] = {}
        self._last_log: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self.first_ns: int | None = None
        self.last_ns = 0
        self.error: str | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._closed = False
        for topic in topics:
            self.add_topic(topic)
        self._thread = threading.Thread(target=self._drain, name="bag_writer", daemon=True)
        self._thread.start()

    # --- caller side -----------------------------------------------------------------
    def add_topic(self, topic: Topic) -> None:
        """Declare a topic (no-op if declared); its channel is written before its first message."""
        if topic.name in self.topics:
            return
        if topic.msgtype not in self._hashes:  # read once per type; fails here, not in the thread
            self._hashes[topic.msgtype] = type_hash(topic.msgtype)
        self.topics[topic.name] = topic
        self.counts[topic.name] = 0
        self._queue.put(topic)

    def add_offers(self, name: str, offers: tuple[Qos, ...]) -> None:
        """Add what newly seen publishers of topic ``name`` offered to what the bag's
        metadata will list (the MCAP channel keeps the offers it was created with)."""
        topic = self.topics.get(name)
        if topic is not None:
            new = tuple(offer for offer in offers if offer not in topic.offers)
            if new:
                self.topics[name] = replace(topic, offers=topic.offers + new)

    def write(self, topic: str, log_time_ns: int, data: bytes, publish_time_ns: int | None = None) -> None:
        """Queue one message; returns at once. Log time: when it was received or published."""
        if topic not in self.topics:
            raise RecordingError(f"{self.folder}: topic {topic} was not declared for this bag")
        self._queue.put((topic, log_time_ns, log_time_ns if publish_time_ns is None else publish_time_ns, data))

    # --- writer thread ---------------------------------------------------------------
    def _register(self, topic: Topic) -> None:
        if topic.msgtype not in self._schemas:
            self._schemas[topic.msgtype] = self._writer.register_schema(
                topic.msgtype, "ros2msg", message_definition(topic.msgtype).encode()
            )
        self._channels[topic.name] = self._writer.register_channel(
            topic.name,
            "cdr",
            self._schemas[topic.msgtype],
            {
                # in the MCAP channel, the offers as a YAML string (as rosbag2 writes them)
                "offered_qos_profiles": yaml.safe_dump(topic.qos_profiles(), sort_keys=False),
                "topic_type_hash": self._hashes[topic.msgtype],
            },
        )

    def _add(self, topic: str, log_ns: int, publish_ns: int, data: bytes) -> None:
        log_ns = max(log_ns, self._last_log.get(topic, log_ns))  # never back in time per channel
        self._writer.add_message(self._channels[topic], log_ns, data, publish_ns, self.counts[topic])
        self._last_log[topic] = log_ns
        self.counts[topic] += 1
        self.first_ns = log_ns if self.first_ns is None else min(self.first_ns, log_ns)
        self.last_ns = max(self.last_ns, log_ns)

    def _flush_chunk(self) -> None:
        self._writer.flush()
        os.fsync(self._stream.fileno())

    def _drain(self) -> None:
        pending = 0  # messages not on disk yet
        last_flush = -float("inf")
        while True:
            timeout = max(0.01, last_flush + self.flush_s - time.monotonic()) if pending else None
            try:
                item = self._queue.get(timeout=timeout)
            except queue.Empty:
                item = _FLUSH_NOW
            if item is None:
                return
            if self.error is not None:
                continue
            try:
                if isinstance(item, Topic):
                    self._register(item)
                elif item is not _FLUSH_NOW:
                    self._add(*item)
                    pending += 1
                if pending and (item is _FLUSH_NOW or time.monotonic() - last_flush >= self.flush_s):
                    self._flush_chunk()  # the first messages at once, then at most every flush_s
                    pending, last_flush = 0, time.monotonic()
            except (OSError, ValueError, RecordingError) as exc:  # disk full, bad type: keep what was written
                self.error = f"{self.file}: {exc}"

    # --- finishing -------------------------------------------------------------------
    def info(self) -> dict[str, Any]:
        """The bag's metadata for what has been written so far."""
        topics = [
            (t.name, t.msgtype, t.qos_profiles(), self._hashes[t.msgtype], self.counts[t.name])
            for t in self.topics.values()
        ]
        return bag_info(self.file.name, topics, self.first_ns or 0, self.last_ns, self.custom_data)

    def close(self) -> Path:
        """Write out what is queued, finish the MCAP file and write metadata.yaml. Idempotent."""
        if self._closed:
            return self.folder
        self._closed = True
        self._queue.put(None)
        self._thread.join()
        info = self.info()
        self._writer.add_metadata(ROSBAG2_RECORD, rosbag2_record(info))
        self._writer.finish()
        self._stream.flush()
        write_metadata(self.folder, info)  # before the lock goes: never a live-looking bag without it
        self._stream.close()
        return self.folder

    def __enter__(self) -> BagRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
