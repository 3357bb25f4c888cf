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
- A disk that fails (full, I/O error) stops the recording, never the caller: the first
  failed write or fsync cuts the file back to its last complete record, the recorder keeps
  a one-line :attr:`BagRecorder.error` and drops what comes after it, and :meth:`close`
  leaves the bag (no ``metadata.yaml``) for ``boom-bag-recover``, which brings back every
  complete chunk. Each chunk is fsynced as it is written, so at most one chunk is lost.

Writing, and finishing the file at :meth:`BagRecorder.close`, happen in a thread of its
own behind a queue, so the caller never waits for the disk and an interrupt of the caller
cannot stop the writer half way. While messages flow, the writer takes them in batches
``BATCH_S`` apart rather than waking for each one. No rclpy here: the caller passes CDR bytes.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import queue
import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2.metadata import dump_qos_v9

from ..errors import RecordingError
from ..files import atomic_path
from ..model.parameters import Parameters
from .run_description import RunDescription

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
    params: Parameters,
    clock_origin_ns: int,
    publish_rate_hz: float,
    command_timeout_s: float,
    *,
    node: str | None = None,
    resimulated_from: str | None = None,
    events_topic: str | None = None,
    clock: str | None = None,
    real_time_factor: float | None = None,
) -> dict[str, str]:
    """The custom data a bag carries so that its run can be simulated again (boom-resim):
    :class:`~.run_description.RunDescription` of the parameters, the stamp of simulated
    time 0, the publish rate, the command timeout, where the run's events are and its clock."""
    description = RunDescription.of(
        params,
        clock_origin_ns,
        publish_rate_hz,
        command_timeout_s,
        node=node,
        resimulated_from=resimulated_from,
        events_topic=events_topic,
        clock=clock,
        real_time_factor=real_time_factor,
    )
    return description.to_custom_data()


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


class BagFile:
    """The MCAP file of a recording, written straight through to its descriptor.

    No hidden buffer: what :meth:`write` accepted is in the file, and a write that fails
    part way is cut off again (``ftruncate`` to where it started), so the file always ends
    at a complete record and ``boom-bag-recover`` finds every chunk before the failure. A
    failed :meth:`sync` cuts the file back to the last successful one: after a failed fsync
    the kernel no longer says which pages reached the disk. After a failure every write
    fails at once: nothing is ever appended behind a gap. The writer (``mcap.writer.Writer``)
    uses :meth:`write`, :meth:`tell` and :meth:`flush`.
    """

    def __init__(self, path: Path):
        self.path = path
        # 0o666: the umask makes it 0644 like every other file of the bag (mkstemp would give 0600)
        self.fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        self.position = 0  # bytes accepted, all in the file
        self.durable = 0  # bytes known to be on the disk (the last successful fsync)
        self.failure: OSError | None = None

    def _write_some(self, data: memoryview) -> int:
        """One ``write(2)``; a seam where the fault-injection tests make the disk fail."""
        return os.write(self.fd, data)

    def _fsync(self) -> None:
        """``fsync(2)``; the other seam of the fault-injection tests."""
        os.fsync(self.fd)

    def write(self, data: bytes) -> int:
        if self.failure is not None:
            raise self.failure
        view = memoryview(data)
        try:
            while view:
                done = self._write_some(view)
                if done <= 0:  # a write that makes no progress would spin for ever
                    raise OSError(errno.EIO, os.strerror(errno.EIO))
                view = view[done:]
        except OSError as exc:
            self._fail(exc, self.position)
            raise
        self.position += len(data)
        return len(data)

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        """Nothing to do: :meth:`write` is unbuffered."""

    def sync(self) -> None:
        """fsync: what was written so far survives a power loss."""
        if self.failure is not None:
            raise self.failure
        try:
            self._fsync()
        except OSError as exc:
            self._fail(exc, self.durable)
            raise
        self.durable = self.position

    def _fail(self, exc: OSError, keep: int) -> None:
        """Remember the failure and cut the file to ``keep`` bytes, which are whole records."""
        self.failure = exc
        self.position = keep
        try:
            os.ftruncate(self.fd, keep)
        except OSError:
            pass  # the disk refuses even that: the reader stops at the incomplete record

    def close(self) -> None:
        """Close the descriptor, which frees the recorder's lock; never raises."""
        if self.fd >= 0:
            fd, self.fd = self.fd, -1
            try:
                os.close(fd)
            except OSError:
                pass  # close(2) frees the descriptor even when it reports an error


_FLUSH_NOW = object()  # the writer's own signal, on a queue timeout: close the chunk in progress
_FINISH = object()  # close() asks the writer thread to finish the file and metadata.yaml
CLOSE_TIMEOUT_S = 60.0  # how long close() waits for the writer (a stalled disk) before it gives up
#: While messages flow, the writer thread wakes this often (s) and takes all that came,
#: instead of once per message: at 100 Hz and six topics, the node's writer thread took
#: 2.1-2.8 % of a core waking per message, 1.0-1.1 % in batches (bench/bench_node.py's
#: real-time run, read per thread).
BATCH_S = 0.05


class BagRecorder:
    """Writes messages to a new bag folder; :meth:`close` finishes the bag.

    Topics are declared at start or later with :meth:`add_topic` (a command topic, once
    its first publisher shows up); :meth:`add_offers` adds what a topic's new publishers
    offered, for the metadata written at close.

    A disk failure (``OSError``: full disk, I/O error), while recording or while finishing,
    never reaches the caller. The recorder stops at the first one: :attr:`error` becomes a
    one-line message naming the file, the cause, and what to do (poll it, or
    :attr:`failed`, as often as you like: they are plain attributes); :meth:`write` then
    returns at once and drops the message; :meth:`close` still returns, with
    :attr:`finished` False and no ``metadata.yaml``, so that the bag is one for
    ``boom-bag-recover``. A failure at start (folder or file cannot be created, header
    cannot be written) raises RecordingError instead: there is no bag to keep.
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
        self.custom_data = dict(custom_data or {})
        self.flush_s = flush_s
        self.topics: dict[str, Topic] = {}
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._hashes: dict[str, str] = {}
        self._definitions: dict[str, bytes] = {}
        self._last_log: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self.first_ns: int | None = None
        self.last_ns = 0
        self.on_disk = 0  # messages in complete chunks in the file (fsynced, but for the last one)
        #: One line on the first disk failure (then nothing more is recorded); None while all is well.
        self.error: str | None = None
        #: True once close() finished the MCAP file and wrote metadata.yaml.
        self.finished = False
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._closed = False
        self._closing = threading.Event()  # set by close(): the writer stops batching
        try:
            for topic in topics:
                self.add_topic(topic)
        except BaseException:  # an unknown message type, or a signal: no bag folder left behind
            self.folder.rmdir()
            raise
        self._stream = self._start_file(chunk_size)  # last: nothing after it can leave a stray file
        self._thread = threading.Thread(target=self._drain, name="bag_writer", daemon=True)
        self._thread.start()

    def _start_file(self, chunk_size: int) -> BagFile:
        """The locked MCAP file with its header and the custom data, on the disk before recording starts."""
        stream = None
        try:
            stream = BagFile(self.file)
            fcntl.flock(stream.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # live until closed or dead
            self._writer = Writer(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
            self._writer.start(profile="ros2", library="boom_hydraulics")
            # custom data (e.g. the run's parameters): in metadata.yaml and, so that a lone
            # .mcap file carries it too, as an MCAP metadata record at once
            if self.custom_data:
                self._writer.add_metadata(CUSTOM_DATA_RECORD, self.custom_data)
            stream.sync()
        except BaseException as exc:  # a disk failure, or a signal (KeyboardInterrupt) under the start
            if stream is not None:
                stream.close()
                self.file.unlink(missing_ok=True)  # created just now, by this call
            self.folder.rmdir()  # likewise, and empty again
            if isinstance(exc, OSError):
                raise RecordingError(f"{self.file}: cannot start the bag ({exc.strerror or exc})") from None
            raise
        return stream

    @property
    def failed(self) -> bool:
        """True once the disk failed: nothing more is recorded, see :attr:`error`."""
        return self.error is not None

    # --- caller side -----------------------------------------------------------------
    def add_topic(self, topic: Topic) -> None:
        """Declare a topic (no-op if declared); its channel is written before its first message."""
        if topic.name in self.topics:
            return
        if topic.msgtype not in self._hashes:  # read once per type; fails here, not in the thread
            self._hashes[topic.msgtype] = type_hash(topic.msgtype)
            self._definitions[topic.msgtype] = message_definition(topic.msgtype).encode()
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
        """Queue one message; returns at once. Log time: when it was received or published.
        After a disk failure (:attr:`failed`), or once closed, the message is dropped."""
        if self.error is not None or self._closed:
            return
        if topic not in self.topics:
            raise RecordingError(f"{self.folder}: topic {topic} was not declared for this bag")
        self._queue.put((topic, log_time_ns, log_time_ns if publish_time_ns is None else publish_time_ns, data))

    # --- writer thread ---------------------------------------------------------------
    def _register(self, topic: Topic) -> None:
        if topic.msgtype not in self._schemas:
            self._schemas[topic.msgtype] = self._writer.register_schema(
                topic.msgtype, "ros2msg", self._definitions[topic.msgtype]
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
        written = self._stream.position
        with self._chunk_write(extra=1):
            self._writer.add_message(self._channels[topic], log_ns, data, publish_ns, self.counts[topic])
        self._last_log[topic] = log_ns
        self.counts[topic] += 1
        self.first_ns = log_ns if self.first_ns is None else min(self.first_ns, log_ns)
        self.last_ns = max(self.last_ns, log_ns)
        if self._stream.position != written:  # the message filled its chunk, which went out: to the disk
            self._sync()

    @contextmanager
    def _chunk_write(self, extra: int = 0) -> Iterator[None]:
        """Around a call that may write a chunk: the writer writes the chunk record, then its
        message indexes. If the disk fails after the chunk record, the file (cut back to the
        failed write) still holds that chunk, so its messages count as kept (``extra``: the
        message being added, which is not counted yet)."""
        written = self._stream.position
        try:
            yield
        except OSError:
            if self._stream.position > written:
                self.on_disk = sum(self.counts.values()) + extra
            raise

    def _sync(self) -> None:
        """fsync: every message added so far is on the disk now (the writer was flushed or finished)."""
        self._stream.sync()
        self.on_disk = sum(self.counts.values())

    def _flush_chunk(self) -> None:
        with self._chunk_write():
            self._writer.flush()
        self._sync()

    def _fail(self, exc: BaseException) -> None:
        """Stop recording at the first failure, with the one line the caller shows."""
        cause = exc.strerror if isinstance(exc, OSError) and exc.strerror else repr(exc)
        total = sum(self.counts.values())
        self.error = (
            f"{self.file}: {cause}; recording stopped after {total} messages, {self.on_disk} of them in "
            f"complete chunks on the disk: run boom-bag-recover {self.folder} to finish the bag with them"
        )

    def _drain(self) -> None:
        """The writer thread: records until close() asks it to finish, or until the disk fails."""
        pending = 0  # messages not on disk yet
        last_flush = -float("inf")
        while True:
            timeout = max(0.01, last_flush + self.flush_s - time.monotonic()) if pending else None
            try:
                item = self._queue.get(timeout=timeout)
            except queue.Empty:
                item = _FLUSH_NOW
            if item is _FINISH:
                self._finish()
                return
            if self.error is not None:
                continue  # failed: drop what was queued before the caller noticed
            try:
                if isinstance(item, Topic):
                    self._register(item)
                elif item is not _FLUSH_NOW:
                    self._add(*item)
                    pending += 1
                drained = self._queue.empty()
                since = time.monotonic() - last_flush
                # the first messages at once, then every flush_s once the batch taken is in; where
                # messages come faster than they are written (never drained), BATCH_S later
                if pending and (item is _FLUSH_NOW or since >= self.flush_s + (0.0 if drained else BATCH_S)):
                    self._flush_chunk()
                    pending, last_flush = 0, time.monotonic()
            except Exception as exc:  # the disk failed (OSError), or a bug: keep what is on the disk
                self._fail(exc)
                pending = 0  # nothing more reaches the disk: no flush to wait for
                continue
            if pending and drained:
                # let the next messages gather, until the chunk is due at the latest (close() ends the wait)
                self._closing.wait(min(BATCH_S, max(0.0, last_flush + self.flush_s - time.monotonic())))

    def _finish(self) -> None:
        """Finish the MCAP file and write metadata.yaml, unless recording failed; then release
        the lock. In the writer thread, so that an interrupted close() cannot cut it short."""
        try:
            if self.error is None:
                try:
                    self._flush_chunk()  # the last messages first: a disk that fails now loses none of them
                    info = self.info()
                    self._writer.add_metadata(ROSBAG2_RECORD, rosbag2_record(info))
                    self._writer.finish()
                    self._sync()
                    write_metadata(self.folder, info)  # before the lock goes: never a live-looking bag without it
                    self.finished = True
                except Exception as exc:
                    self._fail(exc)
        finally:
            self._stream.close()

    # --- finishing -------------------------------------------------------------------
    def info(self) -> dict[str, Any]:
        """The bag's metadata for what has been written so far."""
        topics = [
            (t.name, t.msgtype, t.qos_profiles(), self._hashes[t.msgtype], self.counts[t.name])
            for t in self.topics.values()
        ]
        return bag_info(self.file.name, topics, self.first_ns or 0, self.last_ns, self.custom_data)

    def close(self, timeout_s: float = CLOSE_TIMEOUT_S) -> Path:
        """Write out what is queued, finish the MCAP file and write metadata.yaml; idempotent.
        Returns the bag folder; never raises for a disk failure.

        Afterwards :attr:`finished` tells whether the bag was finished. If not, :attr:`error`
        says why, there is no metadata.yaml, and the MCAP file ends at its last complete
        record: ``boom-bag-recover`` finishes it. The writer thread does the finishing; a
        KeyboardInterrupt while close() waits for it is held back until the bag is finished,
        then raised. The caller should still keep signals away from close() (its first lines
        are not shielded). A writer stuck longer than ``timeout_s`` on a stalled disk is left
        behind, with :attr:`error` set, so that close() always returns.
        """
        if self._closed:
            return self.folder
        self._closed = True
        self._queue.put(_FINISH)
        self._closing.set()
        interrupted = False
        deadline = time.monotonic() + timeout_s
        while self._thread.is_alive() and time.monotonic() < deadline:
            try:
                self._thread.join(timeout=min(1.0, max(0.0, deadline - time.monotonic())))
            except KeyboardInterrupt:
                interrupted = True  # the bag first
        if self._thread.is_alive() and self.error is None:
            self.error = (
                f"{self.file}: the disk did not take the bag's last writes within {timeout_s:g} s; "
                f"run boom-bag-recover {self.folder} once the recorder has exited"
            )
        if interrupted:
            raise KeyboardInterrupt
        return self.folder

    def __enter__(self) -> BagRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
