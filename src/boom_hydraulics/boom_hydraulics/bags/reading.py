"""Reading the drive's signals back from a recorded bag (folder or single .mcap file)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader, AnyReaderError

from ..errors import BagError
from .encoding import DRIVE_STATE, DRIVE_STATE_FIELDS, ENERGY_LEDGER, FLAGS
from .energy import ledger_of_message
from .recording import CUSTOM_DATA_RECORD, MCAP_MAGIC, is_being_recorded
from .run_description import RunDescription

#: How runs are put on a common time axis: t = 0 at the recorded time origin (simulated
#: time 0 of the node), at the first opening of the valve, or at the first message.
ALIGNMENTS = ("origin", "command", "first")


def mcap_files(bag: Path) -> list[Path]:
    """The MCAP file of a single-file bag, or the .mcap files of a bag folder."""
    return [bag] if bag.is_file() else sorted(bag.glob("*.mcap"))


def _truncated(file: Path) -> bool:
    """A finished MCAP file ends with the magic bytes; a killed recorder's file does not."""
    with file.open("rb") as handle:
        if handle.read(8) != MCAP_MAGIC:
            raise BagError(f"{file}: not an MCAP file (wrong magic bytes)")
        handle.seek(0, 2)
        if handle.tell() < 16:
            return True
        handle.seek(-8, 2)
        return handle.read(8) != MCAP_MAGIC


def check_bag_path(path: Path) -> None:
    """Raise BagError, with what to do, unless ``path`` is a finished bag folder or MCAP file."""
    if not path.exists():
        raise BagError(f"{path}: no such bag folder or file")
    files = mcap_files(path)
    if path.is_dir() and not files:
        raise BagError(f"{path}: not a bag: the folder has no .mcap file")
    if any(is_being_recorded(f) for f in files):
        raise BagError(f"{path}: is still being recorded; read it once its recorder has finished")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise BagError(
            f"{path}: has no metadata.yaml: its recording did not finish (the recorder was killed, "
            f"or its disk was full); run boom-bag-recover {path} first"
        )
    for file in files:
        if _truncated(file):
            fix = f"run boom-bag-recover {path}" if path.is_dir() else "run boom-bag-recover on its bag folder"
            raise BagError(
                f"{file}: the file is truncated (its recorder was killed, or its disk was full); {fix} first"
            )
    if path.is_dir():
        check_metadata(path / "metadata.yaml", files)


#: What rosbags reads from metadata.yaml (rosbag2_bagfile_information), and the type it must have.
_METADATA_KEYS = {
    "version": int,
    "storage_identifier": str,
    "relative_file_paths": list,
    "topics_with_message_count": list,
    "duration": dict,
    "starting_time": dict,
    "message_count": int,
}
_TOPIC_KEYS = ("name", "type", "serialization_format")


def check_metadata(file: Path, mcaps: list[Path]) -> None:
    """Raise BagError naming what is wrong unless ``file`` is a readable rosbag2 metadata.yaml:
    UTF-8 text, YAML that parses, and the shape a reader relies on. A damaged one is not
    replaced here (it is the user's); the bag's .mcap file carries the same metadata."""
    fix = (
        f"read its MCAP file {mcaps[0]} directly (it carries the same metadata), or move the damaged file away "
        "and run boom-bag-recover on the folder"
        if len(mcaps) == 1
        else "move the damaged file away and run boom-bag-recover on the folder"
    )
    try:
        text = file.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BagError(
            f"{file}: is not UTF-8 text (byte {exc.start} is 0x{exc.object[exc.start]:02x}); {fix}"
        ) from None
    try:
        content = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise BagError(f"{file}: is not valid YAML{where}; {fix}") from None
    except RecursionError:
        raise BagError(f"{file}: is nested deeper than can be read, so it is no rosbag2 metadata; {fix}") from None
    problem = _metadata_problem(content)
    if problem:
        raise BagError(f"{file}: is not rosbag2 bag metadata ({problem}); {fix}")


def _metadata_problem(content: object) -> str | None:
    """What is missing or of the wrong type in parsed metadata.yaml, or None."""
    info = content.get("rosbag2_bagfile_information") if isinstance(content, dict) else None
    if not isinstance(info, dict):
        return "no rosbag2_bagfile_information mapping"
    for key, kind in _METADATA_KEYS.items():
        if not isinstance(info.get(key), kind) or isinstance(info.get(key), bool):
            return f"{key} is missing or not a{'n' if kind is int else ''} {kind.__name__}"
    if not all(isinstance(name, str) for name in info["relative_file_paths"]):
        return "relative_file_paths holds something other than file names"
    if not isinstance(info["duration"].get("nanoseconds"), int):
        return "duration has no nanoseconds"
    if not isinstance(info["starting_time"].get("nanoseconds_since_epoch"), int):
        return "starting_time has no nanoseconds_since_epoch"
    for entry in info["topics_with_message_count"]:
        topic = entry.get("topic_metadata") if isinstance(entry, dict) else None
        if not isinstance(topic, dict) or not all(isinstance(topic.get(k), str) for k in _TOPIC_KEYS):
            return "a topic without name, type or serialization_format"
        if not isinstance(entry.get("message_count"), int):
            return f"topic {topic['name']} has no message_count"
    return None


def read_custom_data(bag: Path) -> dict[str, str] | None:
    """The run description a boom_hydraulics recorder stored in ``bag`` (None if there is none)."""
    check_bag_path(bag)
    return _custom_data(bag)


def read_run_description(bag: Path) -> RunDescription:
    """The run description of ``bag`` (see :mod:`.run_description`); BagError, with what to
    do, if it has none (not recorded by boom_sim) or one that does not read."""
    custom = read_custom_data(bag)
    if custom is None:
        raise BagError(f"{bag}: no run description (custom data); was it recorded by boom_sim?")
    try:
        return RunDescription.from_custom_data(custom)
    except (KeyError, ValueError, yaml.YAMLError) as exc:
        raise BagError(f"{bag}: the recorded run description is unreadable ({exc})") from None
    except RecursionError:
        raise BagError(f"{bag}: the recorded run description is unreadable (nested deeper than can be read)") from None


def _custom_data(bag: Path) -> dict[str, str] | None:
    try:
        with mcap_files(bag)[0].open("rb") as handle:
            for record in make_reader(handle).iter_metadata():
                if record.name == CUSTOM_DATA_RECORD:
                    return dict(record.metadata)
    except (McapError, OSError, ValueError) as exc:
        raise BagError(f"{bag}: cannot read the bag's metadata ({exc})") from None
    return None


def read_drive_states(bag: str | Path, align: str = "origin") -> dict[str, np.ndarray]:
    """Every DriveState of ``bag`` as arrays, by stamp order.

    ``t`` is in s from the origin chosen by ``align`` (see :data:`ALIGNMENTS`); it is
    computed from integer nanoseconds, so epoch stamps lose no resolution. A bag without a
    recorded origin falls back to its first message.
    """
    if align not in ALIGNMENTS:
        raise BagError(f"unknown alignment {align!r}; choose one of {', '.join(ALIGNMENTS)}")
    path = Path(bag)
    check_bag_path(path)
    try:
        with AnyReader([path]) as reader:
            connections = [c for c in reader.connections if c.msgtype == DRIVE_STATE]
            if not connections:
                topics = ", ".join(sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections)) or "none"
                raise BagError(f"{path}: no {DRIVE_STATE} topic in this bag; topics: {topics}")
            stamps: list[int] = []
            rows = []
            for connection, _, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
                rows.append(tuple(getattr(msg, field) for field in DRIVE_STATE_FIELDS))
    except AnyReaderError as exc:
        raise BagError(f"{path}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except (OSError, ValueError, KeyError) as exc:
        raise BagError(f"{path}: cannot read the bag ({exc})") from None
    if len(rows) < 2:
        raise BagError(f"{path}: only {len(rows)} DriveState message(s); nothing to analyse")
    order = np.argsort(np.array(stamps, dtype=np.int64), kind="stable")
    stamp_ns = np.array(stamps, dtype=np.int64)[order]
    table = np.array(rows, dtype=float)[order]
    out: dict[str, np.ndarray] = {}
    for i, name in enumerate(DRIVE_STATE_FIELDS.values()):
        out[name] = table[:, i].astype(bool) if name in FLAGS else table[:, i]
    origin_ns = _origin_ns(path, align, stamp_ns, out["u"])
    out = {"t": (stamp_ns - origin_ns).astype(float) * 1e-9, **out}
    return out


def read_energy_ledger(bag: str | Path) -> dict[str, float] | None:
    """The energy ledger of ``bag`` at its end: its last EnergyLedger message (by stamp) as the
    integrals of the ledger's terms, J (bags.energy.ledger_of_message); None for a bag without
    one (paper mode, or recorded before the node published it)."""
    messages = read_energy_ledger_messages(bag)
    return ledger_of_message(messages[-1][1]) if messages else None


def read_energy_ledger_messages(bag: str | Path) -> list[tuple[int, Any]]:
    """Every EnergyLedger message of ``bag`` with its stamp (ns), by stamp (as recorded where
    stamps are equal); none for a bag without them."""
    path = Path(bag)
    check_bag_path(path)
    found: list[tuple[int, Any]] = []
    try:
        with AnyReader([path]) as reader:
            connections = [c for c in reader.connections if c.msgtype == ENERGY_LEDGER]
            if not connections:  # (an empty list would read every topic)
                return []
            for connection, _, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                found.append((msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, msg))
    except AnyReaderError as exc:
        raise BagError(f"{path}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except (OSError, ValueError, KeyError) as exc:
        raise BagError(f"{path}: cannot read the bag ({exc})") from None
    return sorted(found, key=lambda item: item[0])


def _origin_ns(path: Path, align: str, stamp_ns: np.ndarray, u: np.ndarray) -> int:
    if align == "origin":
        origin_ns = RunDescription.origin_in(_custom_data(path) or {})  # the bag was checked by the caller
        if origin_ns is not None:
            return origin_ns
    if align == "command":
        opened = np.nonzero(u != 0.0)[0]
        if len(opened):
            return int(stamp_ns[opened[0]])
    return int(stamp_ns[0])
