"""Recovering a bag whose recorder was killed or whose disk failed; boom-bag-recover runs it.

A killed recorder (SIGKILL, power loss), or one whose disk filled up, leaves an MCAP file
without its summary and footer, and no metadata.yaml. Every chunk the recorder completed
is intact on disk. This reads the file record by record, checking each length against
the bytes that are there, and keeps every complete chunk whose contents decompress and
match their CRC (a chunk that does not is dropped and counted), and every complete
message record outside chunks; it stops at the first incomplete record. What was still
in the last, incomplete chunk is lost: at most one chunk, which the node closes at least
every record_flush_s seconds (default 1 s).

The result is whole or nothing. The new MCAP file and metadata.yaml are written and
fsynced under temporary names (``.<name>.<8 characters>.partial``) first; then the
damaged file is renamed to <name>.damaged, the new file takes its name, and metadata.yaml
comes last: its presence says the bag is finished. An interruption at any point leaves a
state that a rerun continues from: the bag as it was; or <name>.damaged (the original)
without a finished <name>, which a rerun recovers from again. Temporary files that an
interrupted run left are removed by the next run, which says so; only names of that
pattern, for this bag's file and metadata.yaml, are touched.

A bag whose recorder is still running is refused: the recorder holds a lock on its file
until it finishes or dies.

Only a killed recording is changed. The node's whole file without metadata.yaml (killed
between the two) gets a metadata.yaml and is not rewritten; a cut file beside a
metadata.yaml is recovered, the old metadata.yaml kept as metadata.yaml.damaged. A whole
file of another tool, another profile than ros2, or no MCAP file at all is refused before
anything changes.
"""

from __future__ import annotations

import fcntl
import mmap
import os
import re
import secrets
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import yaml
import zstandard
from mcap.writer import CompressionType, Writer

from ..errors import BagError
from .recording import CUSTOM_DATA_RECORD, MCAP_MAGIC, ROSBAG2_RECORD, bag_info, is_being_recorded, rosbag2_record

RECOVERED_LIBRARY = "boom_hydraulics (recovered)"  # the header's library field of a file this module wrote
DAMAGED_SUFFIX = ".damaged"
# MCAP opcodes (the specification's record types) this reader acts on
_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK, _METADATA, _DATA_END = (
    0x01,
    0x02,
    0x03,
    0x04,
    0x05,
    0x06,
    0x0C,
    0x0F,
)
_RECORD_HEAD = 9  # opcode (1 byte) and content length (uint64)
_FOOTER_RECORD = _RECORD_HEAD + 20  # the footer: summary start, summary offset start (uint64), summary CRC (uint32)
RECORDER_LIBRARY = "boom_hydraulics"  # the header's library field of the node's recorder (bags.recording)
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # a message's channel id, sequence, log time, publish time


class _CutError(Exception):
    """The bytes end inside a record."""


class _DamagedError(Exception):
    """A record's content does not parse, or a chunk does not decompress or match its CRC."""


class _Cursor:
    """Reads little-endian fields from ``data``, each one checked against the bytes left."""

    def __init__(self, data: memoryview):
        self.data = data
        self.pos = 0

    def take(self, n: int) -> memoryview:
        if n > len(self.data) - self.pos:
            raise _CutError
        self.pos += n
        return self.data[self.pos - n : self.pos]

    def uint(self, size: int) -> int:
        return int.from_bytes(self.take(size), "little")

    def string(self) -> str:
        try:
            return str(self.take(self.uint(4)), "utf-8")
        except UnicodeDecodeError:
            raise _DamagedError from None

    def string_map(self) -> dict[str, str]:
        inner = _Cursor(self.take(self.uint(4)))
        pairs = {}
        while inner.pos < len(inner.data):
            key = inner.string()
            pairs[key] = inner.string()
        return pairs


@dataclass
class Salvage:
    """What a damaged MCAP file still holds, and where reading it stopped."""

    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)  # id: name, encoding, data
    channels: dict[int, tuple[str, str, int, dict[str, str]]] = field(default_factory=dict)  # topic, enc, schema, meta
    messages: list[tuple[int, int, int, int, bytes]] = field(default_factory=list)  # channel, seq, log, publish, data
    metadata: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    dropped_chunks: int = 0  # complete chunks whose contents were damaged
    orphans: int = 0  # messages whose channel was in a dropped chunk
    stop: int = 0  # the offset where reading stopped
    complete: bool = False  # True when the data section ended properly (a finished file)


def _records(data: memoryview) -> Iterator[tuple[int, memoryview, int]]:
    """(opcode, content, offset) of each complete record; ends before the first incomplete one."""
    pos = 0
    while len(data) - pos >= _RECORD_HEAD:
        opcode = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if length > len(data) - pos - _RECORD_HEAD:
            return
        yield opcode, data[pos + _RECORD_HEAD : pos + _RECORD_HEAD + length], pos
        pos += _RECORD_HEAD + length


def _chunk_data(content: memoryview) -> memoryview:
    """The records inside a chunk: decompressed, with size and CRC checked."""
    cursor = _Cursor(content)
    cursor.take(16)  # message start and end time
    size, crc = cursor.uint(8), cursor.uint(4)
    compression = cursor.string()
    packed = cursor.take(cursor.uint(8))
    try:
        if compression == "":
            raw = bytes(packed)
        elif compression == "zstd":
            raw = zstandard.ZstdDecompressor().decompress(packed, max_output_size=size)
        elif compression == "lz4":
            import lz4.frame  # the recorder writes zstd; lz4 only if another writer used it

            raw = lz4.frame.decompress(bytes(packed))
        else:
            raise _DamagedError
    except (zstandard.ZstdError, RuntimeError, ImportError, MemoryError):
        raise _DamagedError from None
    if len(raw) != size or (crc and zlib.crc32(raw) != crc):
        raise _DamagedError
    return memoryview(raw)


def _take_record(found: Salvage, opcode: int, content: memoryview) -> None:
    """Add a schema, channel or message record to ``found``."""
    if opcode == _MESSAGE:  # the common case, read without the cursor's per-field checks
        if len(content) < _MESSAGE_HEAD.size:
            raise _CutError
        cid, seq, log_ns, publish_ns = _MESSAGE_HEAD.unpack_from(content)
        if cid in found.channels:
            found.messages.append((cid, seq, log_ns, publish_ns, bytes(content[_MESSAGE_HEAD.size :])))
        else:
            found.orphans += 1
        return
    cursor = _Cursor(content)
    if opcode == _SCHEMA:
        sid, name, encoding = cursor.uint(2), cursor.string(), cursor.string()
        found.schemas[sid] = (name, encoding, bytes(cursor.take(cursor.uint(4))))
    elif opcode == _CHANNEL:
        cid, sid, topic, encoding = cursor.uint(2), cursor.uint(2), cursor.string(), cursor.string()
        found.channels[cid] = (topic, encoding, sid, cursor.string_map())


def _take_chunk(found: Salvage, content: memoryview) -> None:
    """Every record of a chunk, or none of them (a chunk that is damaged anywhere is dropped)."""
    inner = Salvage(schemas=dict(found.schemas), channels=dict(found.channels))
    try:
        records = _chunk_data(content)
        end = 0
        for opcode, body, offset in _records(records):
            _take_record(inner, opcode, body)
            end = offset + _RECORD_HEAD + len(body)
        if end != len(records):
            raise _CutError
    except (_CutError, _DamagedError):
        found.dropped_chunks += 1
        return
    found.schemas, found.channels = inner.schemas, inner.channels
    found.messages += inner.messages
    found.orphans += inner.orphans


def salvage(data: bytes | memoryview) -> Salvage:
    """What any byte prefix of an MCAP file holds (see the module's description); never raises
    for damaged or cut contents, only BagError when the bytes are not an MCAP file at all."""
    data = memoryview(data)
    if bytes(data[: len(MCAP_MAGIC)]) != MCAP_MAGIC[: len(data)]:
        raise BagError("not an MCAP file (wrong magic bytes)")
    found = Salvage()
    body = data[len(MCAP_MAGIC) :]
    for opcode, content, offset in _records(body):
        found.stop = len(MCAP_MAGIC) + offset
        if opcode in (_DATA_END, _FOOTER):
            found.complete = True
            return found
        try:
            if opcode == _CHUNK:
                _take_chunk(found, content)
            elif opcode == _METADATA:
                cursor = _Cursor(content)
                name = cursor.string()
                if name != ROSBAG2_RECORD:  # rewritten for what was kept
                    found.metadata.append((name, cursor.string_map()))
            elif opcode != _HEADER:
                _take_record(found, opcode, content)  # unchunked records; indexes and others are skipped
        except (_CutError, _DamagedError):
            pass  # a complete record with damaged contents: skip it, the next one starts after it
        found.stop = len(MCAP_MAGIC) + offset + _RECORD_HEAD + len(content)
    return found


def _finished_by_us(path: Path) -> bool:
    """True for a finished MCAP file that this module wrote: an earlier run's result."""
    try:
        if not _whole(path):
            return False
        header = _header(path)
    except (OSError, BagError):
        return False
    return header is not None and header[1] == RECOVERED_LIBRARY


# --- writing ----------------------------------------------------------------------------
def _partial_pattern(file_name: str) -> re.Pattern[str]:
    """Temporary names of this module and of files.atomic_path for the bag's file and metadata.yaml."""
    names = f"(?:{re.escape(file_name)}|metadata\\.yaml)"
    return re.compile(rf"\.{names}\.[a-z0-9_]{{8}}\.partial")


def _remove_leftovers(bag: Path, file_name: str) -> list[Path]:
    """Remove what an interrupted earlier run left; returns the names removed."""
    pattern = _partial_pattern(file_name)
    removed = []
    for item in sorted(bag.iterdir()):
        if pattern.fullmatch(item.name) and item.is_file() and not item.is_symlink():
            try:
                item.unlink()
            except OSError as exc:
                raise BagError(f"{item}: cannot remove this leftover of an interrupted run ({exc.strerror})") from None
            removed.append(item)
    return removed


def _new_partial(final: Path) -> tuple[Path, int]:
    """A new temporary file beside ``final``, with the mode any new file gets (0666 & ~umask)."""
    while True:
        tmp = final.with_name(f".{final.name}.{secrets.token_hex(4)}.partial")
        try:
            return tmp, os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        except FileExistsError:
            continue


def _topics(found: Salvage, counts: dict[int, int]) -> list[tuple[str, str, list[dict], str, int]]:
    return [
        (
            topic,
            found.schemas[sid][0] if sid in found.schemas else "",
            yaml.safe_load(meta.get("offered_qos_profiles", "[]")) or [],
            meta.get("topic_type_hash", ""),
            counts[cid],
        )
        for cid, (topic, _, sid, meta) in found.channels.items()
    ]


def _write_mcap(handle: object, file_name: str, found: Salvage) -> dict:
    """A finished MCAP file of the salvaged records; returns the bag's metadata."""
    writer = Writer(handle, compression=CompressionType.ZSTD)
    writer.start(profile="ros2", library=RECOVERED_LIBRARY)
    for name, pairs in found.metadata:
        writer.add_metadata(name, pairs)
    new_schema = {sid: writer.register_schema(*schema) for sid, schema in found.schemas.items()}
    new_channel = {
        cid: writer.register_channel(topic, encoding, new_schema.get(sid, 0), meta)
        for cid, (topic, encoding, sid, meta) in found.channels.items()
    }
    for cid, seq, log_ns, publish_ns, data in found.messages:
        writer.add_message(new_channel[cid], log_ns, data, publish_ns, seq)
    info = _info(file_name, found)
    writer.add_metadata(ROSBAG2_RECORD, rosbag2_record(info))
    writer.finish()
    return info


def _info(file_name: str, found: Salvage) -> dict:
    """The bag's metadata (metadata.yaml's content) of the salvaged records."""
    counts = dict.fromkeys(found.channels, 0)
    for message in found.messages:
        counts[message[0]] += 1
    custom = next((pairs for name, pairs in found.metadata if name == CUSTOM_DATA_RECORD), {})
    times = [m[2] for m in found.messages]
    return bag_info(file_name, _topics(found, counts), min(times, default=0), max(times, default=0), dict(custom))


def _write_partial(final: Path, fill: object) -> Path:
    """``fill(handle)`` into a fsynced temporary file beside ``final``; removed again if anything fails."""
    tmp, fd = _new_partial(final)
    try:
        with os.fdopen(fd, "wb") as handle:
            fill(handle)
            handle.flush()
            os.fsync(handle.fileno())
    except BaseException:
        tmp.unlink(missing_ok=True)  # ours: created above
        raise
    return tmp


def _sync_folder(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


# --- the tool ---------------------------------------------------------------------------
@dataclass
class Recovery:
    """What :func:`recover` did."""

    file: Path  # the finished MCAP file
    damaged: Path | None  # the original, kept (None: the file was whole, only metadata.yaml was written)
    messages: int  # messages kept
    dropped_chunks: int  # complete chunks whose contents were damaged
    orphans: int  # messages dropped because their channel was lost
    removed: list[Path]  # leftovers of an interrupted earlier run, removed
    resumed: bool  # True when an earlier run had renamed the original already
    old_metadata: Path | None = None  # a metadata.yaml beside a cut file, kept under this name


def _mcap_name(bag: Path) -> str:
    """The name of the bag's one MCAP file, also when an interrupted run left only its .damaged."""
    names = {f.name for f in bag.glob("*.mcap")} | {f.name[: -len(DAMAGED_SUFFIX)] for f in bag.glob("*.mcap.damaged")}
    if len(names) != 1:
        raise BagError(f"{bag}: expected one .mcap file, found {len(names)}")
    return names.pop()


def _read(source: Path) -> Salvage:
    why = None
    try:
        with source.open("rb") as handle:
            size = os.fstat(handle.fileno()).st_size
            if size == 0:
                return salvage(b"")
            with mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
                try:
                    found = salvage(data)
                except BagError as exc:  # its traceback holds views of the map: let it go before the map closes
                    why = str(exc)
    except OSError as exc:
        raise BagError(f"{source}: cannot read it ({exc.strerror or exc})") from None
    if why is not None:
        raise BagError(f"{source}: {why}")
    return found


def _header(path: Path) -> tuple[str, str] | None:
    """The profile and library of an MCAP file's header record (None where it has none), read
    whole by its stated length, however long its strings."""
    try:
        with path.open("rb") as handle:
            head = handle.read(len(MCAP_MAGIC) + _RECORD_HEAD)
            if len(head) == len(MCAP_MAGIC) + _RECORD_HEAD:  # the record's length: read the rest (what is there)
                length = int.from_bytes(head[-8:], "little")
                head += handle.read(min(length, os.fstat(handle.fileno()).st_size))
    except OSError as exc:
        raise BagError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if head[: len(MCAP_MAGIC)] != MCAP_MAGIC[: len(head)]:  # a prefix of the magic: cut at the start
        raise BagError(f"{path}: not an MCAP file (wrong magic bytes); nothing was changed")
    try:
        for opcode, content, _ in _records(memoryview(head)[len(MCAP_MAGIC) :]):
            if opcode != _HEADER:
                return None
            cursor = _Cursor(content)
            return cursor.string(), cursor.string()
    except (_CutError, _DamagedError):
        return None
    return None


def _whole(path: Path) -> bool:
    """True for an MCAP file that ends in its footer record and the magic bytes: it was finished."""
    tail = _FOOTER_RECORD + len(MCAP_MAGIC)
    with path.open("rb") as handle:
        handle.seek(0, os.SEEK_END)
        if handle.tell() < len(MCAP_MAGIC) + tail:
            return False
        handle.seek(-tail, os.SEEK_END)
        end = handle.read(tail)
    return (
        end[-len(MCAP_MAGIC) :] == MCAP_MAGIC
        and end[0] == _FOOTER
        and int.from_bytes(end[1:_RECORD_HEAD], "little") == _FOOTER_RECORD - _RECORD_HEAD
    )


def recover(bag: Path) -> Recovery:
    """Finish ``bag`` (folder) in place; see the module's description for the order of steps.
    One run at a time per bag (a lock on the folder): a second run would take the first
    one's temporary files for leftovers."""
    if not bag.is_dir():
        raise BagError(f"{bag}: not a bag folder")
    try:
        fd = os.open(bag, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as exc:
        raise BagError(f"{bag}: cannot open the bag folder ({exc.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise BagError(f"{bag}: another boom-bag-recover is working on it; wait for it to end") from None
        return _recover(bag)
    finally:
        os.close(fd)


def _recover(bag: Path) -> Recovery:
    """Which state the folder is in decides what is done; anything that is not a killed
    recording (or an interrupted run of this tool) is refused before anything changes."""
    name = _mcap_name(bag)
    target, kept = bag / name, bag / f"{name}{DAMAGED_SUFFIX}"
    metadata = bag / "metadata.yaml"
    if target.exists() and is_being_recorded(target):
        raise BagError(f"{bag}: is still being recorded; stop its recorder first (a killed one frees the bag)")
    resumed = kept.exists()
    if resumed and target.exists() and not _finished_by_us(target):
        raise BagError(f"{kept} exists already; move it out of the bag folder first")
    if resumed and metadata.exists():
        raise BagError(f"{bag}: has a metadata.yaml already, so it was finished; nothing to recover")
    if not resumed:
        header = _header(target)
        if header is not None and header[0] != "ros2":  # (none: cut before its header ended)
            raise BagError(
                f"{target}: is not a rosbag2 recording (profile {header[0]!r}); nothing was changed "
                "(boom-bag-recover finishes the bags of the node and of ros2 bag record)"
            )
        if header is not None and _whole(target):
            if metadata.exists():
                raise BagError(f"{bag}: has a metadata.yaml already, so it was finished; nothing to recover")
            if header[1] != RECORDER_LIBRARY:
                raise BagError(
                    f"{target}: is a whole MCAP file (written by {header[1] or 'an unnamed library'}), not a killed "
                    "recording; nothing was changed (every reader here reads a lone .mcap file as it is)"
                )
            return _describe(bag, target, _remove_leftovers(bag, name))
        if metadata.exists() and (bag / f"metadata.yaml{DAMAGED_SUFFIX}").exists():
            raise BagError(
                f"{bag / f'metadata.yaml{DAMAGED_SUFFIX}'} exists already; move it out of the bag folder first"
            )
    removed = _remove_leftovers(bag, name)
    source = kept if resumed else target
    found = _read(source)
    if not found.channels:
        raise BagError(f"{source}: no channel survived; nothing to recover")
    found.messages.sort(key=lambda m: m[2])  # by log time; stable, so per channel as recorded
    old_metadata = bag / f"metadata.yaml{DAMAGED_SUFFIX}"
    # a finished bag whose file was cut since (a copy broken off): its metadata.yaml is kept aside,
    # renamed with the rest once the new files are written
    aside = old_metadata if not resumed and metadata.exists() else None
    _place(bag, source, target, kept, found, aside)
    return Recovery(
        target,
        kept,
        len(found.messages),
        found.dropped_chunks,
        found.orphans,
        removed,
        resumed,
        old_metadata if old_metadata.exists() else None,  # (also where an interrupted run had moved it)
    )


def _describe(bag: Path, file: Path, removed: list[Path]) -> Recovery:
    """metadata.yaml for the node's whole MCAP file: its recorder was killed after finishing the
    file and before writing metadata.yaml. The file itself is not changed."""
    found = _read(file)
    text = yaml.safe_dump({"rosbag2_bagfile_information": _info(file.name, found)}, sort_keys=False).encode()
    try:
        tmp = _write_partial(bag / "metadata.yaml", lambda handle: handle.write(text))
    except OSError as exc:
        raise BagError(f"{exc.filename or bag}: {exc.strerror or exc}; nothing was changed") from None
    try:
        os.replace(tmp, bag / "metadata.yaml")
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise BagError(f"{exc.filename or bag}: {exc.strerror or exc}; nothing was changed") from None
    try:
        _sync_folder(bag)
    except OSError as exc:  # metadata.yaml is in place, whole; whether it outlives a power cut is not sure
        raise BagError(
            f"{exc.filename or bag}: {exc.strerror or exc}; metadata.yaml is written but the folder could not be "
            f"synced to disk: the bag reads now, and after a power cut boom-bag-recover {bag} writes it again"
        ) from None
    return Recovery(file, None, len(found.messages), found.dropped_chunks, found.orphans, removed, False)


def _place(bag: Path, source: Path, target: Path, kept: Path, found: Salvage, metadata_aside: Path | None) -> None:
    """Write both files whole under temporary names, then rename them into place (the bag's old
    metadata.yaml first to ``metadata_aside``, where given)."""
    need = f"about {max(1, source.stat().st_size >> 20)} MiB"
    written: list[Path] = []
    try:
        info: dict = {}

        def fill_mcap(handle: object) -> None:
            info.update(_write_mcap(handle, target.name, found))

        written.append(_write_partial(target, fill_mcap))
        text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False).encode()
        written.append(_write_partial(bag / "metadata.yaml", lambda handle: handle.write(text)))
    except OSError as exc:
        for tmp in written:
            tmp.unlink(missing_ok=True)
        raise BagError(
            f"{exc.filename or target}: {exc.strerror or exc}; nothing was changed, the bag is as it was "
            f"(free {need} and run boom-bag-recover {bag} again)"
        ) from None
    except BaseException:
        for tmp in written:
            tmp.unlink(missing_ok=True)
        raise
    new_mcap, new_yaml = written
    try:
        if metadata_aside is not None:  # first: without metadata.yaml the bag is one a rerun continues
            os.rename(bag / "metadata.yaml", metadata_aside)
        if source == target:
            os.rename(target, kept)  # the original stays, under a new name
        os.replace(new_mcap, target)
        os.replace(new_yaml, bag / "metadata.yaml")  # last: a bag with metadata.yaml is finished
        _sync_folder(bag)
    except OSError as exc:
        raise BagError(
            f"{exc.filename or bag}: {exc.strerror or exc}; the bag is half renamed: "
            f"run boom-bag-recover {bag} again to finish it"
        ) from None
