"""Reading the drive's signals back from a recorded bag (folder or single .mcap file)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader, AnyReaderError

from ..errors import BagError
from .encoding import DRIVE_STATE, DRIVE_STATE_FIELDS, FLAGS
from .recording import CUSTOM_DATA_RECORD, MCAP_MAGIC, is_being_recorded

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
            f"{path}: has no metadata.yaml: its recorder was killed before finishing it; "
            f"run boom-bag-recover {path} first"
        )
    for file in files:
        if _truncated(file):
            fix = f"run boom-bag-recover {path}" if path.is_dir() else "run boom-bag-recover on its bag folder"
            raise BagError(f"{file}: the file is truncated (its recorder was killed?); {fix} first")


def read_custom_data(bag: Path) -> dict[str, str] | None:
    """The run description a boom_hydraulics recorder stored in ``bag`` (None if there is none)."""
    check_bag_path(bag)
    return _custom_data(bag)


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


def _origin_ns(path: Path, align: str, stamp_ns: np.ndarray, u: np.ndarray) -> int:
    if align == "origin":
        custom = _custom_data(path) or {}  # the bag was checked by the caller
        if "clock_origin_ns" in custom:
            return int(custom["clock_origin_ns"])
    if align == "command":
        opened = np.nonzero(u != 0.0)[0]
        if len(opened):
            return int(stamp_ns[opened[0]])
    return int(stamp_ns[0])
