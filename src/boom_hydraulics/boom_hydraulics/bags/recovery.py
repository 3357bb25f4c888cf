"""Recovering a bag whose recorder was killed (SIGKILL, power loss); boom-bag-recover runs it.

A killed recorder leaves an MCAP file without its summary and footer, and no
metadata.yaml. Every chunk the recorder completed is intact on disk: this reads the file
record by record up to the first incomplete one and writes a finished MCAP file with
those messages, under the original name, with metadata.yaml. The damaged file is kept
beside it as <name>.damaged. What was still in the last, incomplete chunk is lost: at
most one chunk, which the node closes at least every record_flush_s seconds (default 1 s).

A bag whose recorder is still running is refused: the recorder holds a lock on its file
until it finishes or dies.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import yaml
from mcap.exceptions import McapError
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from ..errors import BagError
from .recording import ROSBAG2_RECORD, bag_info, is_being_recorded, rosbag2_record, write_metadata


def _salvage(path: Path) -> tuple[dict, dict, list[Message], list[Metadata]]:
    """Schemas, channels, messages and metadata records up to the first incomplete record."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    messages: list[Message] = []
    metadata: list[Metadata] = []
    with path.open("rb") as handle:
        try:
            for record in StreamReader(handle, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    messages.append(record)
                elif isinstance(record, Metadata) and record.name != ROSBAG2_RECORD:
                    metadata.append(record)
        except (McapError, EOFError, ValueError, OSError):
            pass  # the truncated tail: everything before it is kept
    return schemas, channels, messages, metadata


def _write_mcap(
    path: Path, file_name: str, schemas: dict, channels: dict, messages: list[Message], metadata: list[Metadata]
) -> dict:
    """A finished MCAP file of the salvaged records at ``path`` (to be named ``file_name``);
    returns the bag's metadata."""
    counts = {cid: 0 for cid in channels}
    with path.open("wb") as handle:
        writer = Writer(handle, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="boom_hydraulics (recovered)")
        for record in metadata:
            writer.add_metadata(record.name, record.metadata)
        new_schema = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in schemas.items()}
        new_channel = {
            cid: writer.register_channel(c.topic, c.message_encoding, new_schema[c.schema_id], c.metadata)
            for cid, c in channels.items()
        }
        for m in messages:
            writer.add_message(new_channel[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
            counts[m.channel_id] += 1
        custom = next((r.metadata for r in metadata if r.name == "boom_hydraulics"), {})
        info = bag_info(
            file_name,
            [
                (
                    c.topic,
                    schemas[c.schema_id].name,
                    yaml.safe_load(c.metadata.get("offered_qos_profiles", "[]")) or [],
                    c.metadata.get("topic_type_hash", ""),
                    counts[cid],
                )
                for cid, c in channels.items()
            ],
            messages[0].log_time if messages else 0,
            messages[-1].log_time if messages else 0,
            dict(custom),
        )
        writer.add_metadata(ROSBAG2_RECORD, rosbag2_record(info))
        writer.finish()
    return info


def recover(bag: Path) -> tuple[Path, int]:
    """Finish ``bag`` (folder) in place; returns the MCAP file and the number of messages kept."""
    if not bag.is_dir():
        raise BagError(f"{bag}: not a bag folder")
    files = sorted(bag.glob("*.mcap"))
    if len(files) != 1:
        raise BagError(f"{bag}: expected one .mcap file, found {len(files)}")
    damaged = files[0]
    if is_being_recorded(damaged):
        raise BagError(f"{bag}: is still being recorded; stop its recorder first (a killed one frees the bag)")
    if (bag / "metadata.yaml").exists():
        raise BagError(f"{bag}: has a metadata.yaml already, so it was finished; nothing to recover")
    kept = damaged.with_name(f"{damaged.name}.damaged")
    if kept.exists():
        raise BagError(f"{kept} exists already; move it out of the bag folder first")
    schemas, channels, messages, metadata = _salvage(damaged)
    if not channels:
        raise BagError(f"{damaged}: no channel survived; nothing to recover")
    messages.sort(key=lambda m: m.log_time)
    handle, name = tempfile.mkstemp(prefix=f".{damaged.name}.", suffix=".partial", dir=bag)
    os.close(handle)
    tmp = Path(name)
    try:
        info = _write_mcap(tmp, damaged.name, schemas, channels, messages, metadata)
        os.rename(damaged, kept)  # the damaged file stays, under a new name
        os.rename(tmp, damaged)
    except BaseException:
        tmp.unlink(missing_ok=True)  # ours
        raise
    write_metadata(bag, info)
    return damaged, len(messages)
