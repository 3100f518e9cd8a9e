"""Recording files: one directory per robot, MCAP files rotated by time and size.

A file is named after the time of its first message, in nanoseconds since the epoch, and
the process that wrote it (``1732431600000000000-ab12cd.mcap``), so files sort by time and
two server processes never write the same file. Its messages run until the next file's
name. Files use the ``ros1`` profile: ``ros1msg`` schemas and ``ros1`` messages, in zstd
chunks of ``CHUNK_BYTES`` so a stop mid-file loses at most one chunk; ``open_messages``
reads a finished file by its index and an unfinished one record by record, and
``repair`` rewrites an unfinished file with its summary.

A file is being written exactly while its writer holds an exclusive ``flock`` on it, in
whichever server process that writer is (the recording directory is shared in the scaled
mode). The kernel drops the lock when the writer closes the file or its process dies, even
by kill -9, so retention (``delete_if_closed``) and repair (``repair_all``) take a file
only once they hold its lock themselves: never one a live process is writing, and at once
one a dead process left.
"""

from __future__ import annotations

import fcntl
import os
import struct
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, NamedTuple

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from telemetry.domain import ros1

CHUNK_BYTES = 256 * 1024
SIZE_EVERY = 64
SUFFIX = ".mcap"
LIBRARY = "cloudnav"
PROCESS_TOKEN = uuid.uuid4().hex[:6]
_MAGIC = b"\x89MCAP0\r\n"


class Record(NamedTuple):
    """One recorded message: channel (topic), ROS 1 type and definition, time, bytes."""

    topic: str
    type_name: str
    schema: bytes
    log_time: int
    data: bytes


@dataclass(frozen=True, order=True)
class RecordingFile:
    start_ns: int
    path: Path

    @property
    def size(self) -> int:
        try:
            return self.path.stat().st_size
        except FileNotFoundError:
            return 0

    @property
    def last_ns(self) -> int:
        """When the file was last written to (its last message, near enough)."""
        try:
            return self.path.stat().st_mtime_ns
        except FileNotFoundError:
            return self.start_ns


def robot_dir(root: Path, robot: str) -> Path:
    return root / robot


def files_of(root: Path, robot: str) -> list[RecordingFile]:
    """The robot's files, oldest first."""
    directory = robot_dir(root, robot)
    if not directory.is_dir():
        return []
    found = []
    for path in directory.iterdir():
        start = _start_of(path)
        if start is not None:
            found.append(RecordingFile(start, path))
    return sorted(found)


def _start_of(path: Path) -> int | None:
    if path.suffix != SUFFIX:
        return None
    head = path.stem.split("-", 1)[0]
    return int(head) if head.isdigit() else None


def files_between(root: Path, robot: str, start_ns: int, end_ns: int) -> list[RecordingFile]:
    """The files that may hold messages in ``[start_ns, end_ns]``."""
    files = files_of(root, robot)
    chosen = []
    for i, f in enumerate(files):
        following = files[i + 1].start_ns if i + 1 < len(files) else None
        if f.start_ns <= end_ns and (following is None or following > start_ns):
            chosen.append(f)
    return chosen


class McapSink:
    """An MCAP writer on ``out`` registering ROS 1 schemas and channels as they come."""

    def __init__(self, out: IO[bytes], chunk_size: int = CHUNK_BYTES) -> None:
        self.writer = Writer(out, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self.writer.start(profile=ros1.PROFILE, library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}

    def channel(self, topic: str, type_name: str, schema: bytes) -> int:
        channel_id = self._channels.get(topic)
        if channel_id is None:
            schema_id = self._schemas.get(type_name)
            if schema_id is None:
                schema_id = self._schemas[type_name] = self.writer.register_schema(
                    type_name, ros1.SCHEMA_ENCODING, schema
                )
            channel_id = self._channels[topic] = self.writer.register_channel(
                topic, ros1.MESSAGE_ENCODING, schema_id
            )
        return channel_id

    def add(self, record: Record) -> None:
        channel_id = self.channel(record.topic, record.type_name, record.schema)
        self.writer.add_message(channel_id, record.log_time, record.data, record.log_time)

    def flush(self) -> None:
        """End the chunk being filled and write it out, so a reader of the file sees every
        message added so far (what an export asks for before it reads)."""
        self.writer.flush()  # type: ignore[no-untyped-call]

    def finish(self) -> None:
        self.writer.finish()  # type: ignore[no-untyped-call]


class RotatingFiles:
    """The files of one robot being recorded: a new one past ``max_seconds`` or ``max_bytes``."""

    def __init__(self, root: Path, robot: str, max_seconds: float, max_bytes: int) -> None:
        self.directory = robot_dir(root, robot)
        self.max_ns = int(max_seconds * 1e9)
        self.max_bytes = max_bytes
        self._out: IO[bytes] | None = None
        self._sink: McapSink | None = None
        self._opened_ns = 0
        self._writes = 0
        self.path: Path | None = None

    def write(self, record: Record) -> None:
        """Append ``record``; raises OSError when the disk refuses."""
        if self._sink is None or self._due(record.log_time):
            self.close()
            self._open(record.log_time)
        assert self._sink is not None
        self._sink.add(record)

    def _due(self, now_ns: int) -> bool:
        assert self._out is not None
        if now_ns - self._opened_ns >= self.max_ns:
            return True
        # the size is looked at every SIZE_EVERY messages: a file passes its size by less
        # than that many messages, and writing one costs no system call for it
        self._writes += 1
        return self._writes % SIZE_EVERY == 0 and self._out.tell() >= self.max_bytes

    def _open(self, start_ns: int) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        self.path = self.directory / f"{start_ns}-{PROCESS_TOKEN}{SUFFIX}"
        self._out = _open_locked(self.path)
        self._sink = McapSink(self._out)
        self._opened_ns = start_ns

    def flush(self) -> None:
        """Write out the current file's open chunk (a no-op when none is open)."""
        if self._sink is not None:
            self._sink.flush()

    def close(self) -> None:
        """Finish the current file (its summary and footer); a no-op when none is open."""
        sink, out = self._sink, self._out
        self._sink = self._out = None
        self.path = None
        try:
            if sink is not None:
                sink.finish()
        finally:
            if out is not None:
                out.close()


def _open_locked(path: Path) -> IO[bytes]:
    """Open ``path`` for writing and hold its lock until it is closed.

    Between the file's creation and its lock, another process may have claimed it as
    closed and deleted it (retention) or replaced it (repair): then it is opened again, so
    what is written always goes into the file at ``path``."""
    while True:
        out = open(path, "wb")  # noqa: SIM115 (closed by RotatingFiles.close())
        fcntl.flock(out.fileno(), fcntl.LOCK_EX)
        try:
            if os.stat(path).st_ino == os.fstat(out.fileno()).st_ino:
                return out
        except FileNotFoundError:
            pass
        out.close()


@contextmanager
def claimed(path: Path) -> Iterator[bool]:
    """Yield True, holding ``path``'s lock for the block, when no writer holds it (the
    file is closed, or its writer's process is dead); False when one is writing it or the
    file is gone."""
    try:
        probe = open(path, "rb")  # noqa: SIM115 (closed below)
    except FileNotFoundError:
        yield False
        return
    with probe:
        try:
            fcntl.flock(probe.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        yield True


def delete_if_closed(path: Path) -> bool:
    """Delete ``path`` unless a live writer holds it; True if it was deleted."""
    with claimed(path) as closed:
        if closed:
            path.unlink(missing_ok=True)
        return closed


def finished(path: Path) -> bool:
    """True when ``path`` ends with MCAP's closing magic (its summary was written)."""
    try:
        with open(path, "rb") as f:
            f.seek(-len(_MAGIC), os.SEEK_END)
            return f.read() == _MAGIC
    except OSError:
        return False


def end_of(f: RecordingFile) -> int:
    """The time of the last message of a finished file (from its summary), else of its
    last write."""
    if finished(f.path):
        try:
            with open(f.path, "rb") as stream:
                summary = make_reader(stream).get_summary()
            if summary is not None and summary.statistics is not None:
                return int(summary.statistics.message_end_time)
        except (McapError, OSError, ValueError):
            pass
    return f.last_ns


def open_messages(path: Path, start_ns: int, end_ns: int) -> Iterator[Record]:
    """The messages of ``path`` in ``[start_ns, end_ns]``, in time order for a finished
    file (by its chunk index, so a seek costs one chunk) and in file order for one still
    being written or cut short, up to its last complete record."""
    if finished(path):
        yield from _indexed(path, start_ns, end_ns)
    else:
        yield from _streamed(path, start_ns, end_ns)


def _indexed(path: Path, start_ns: int, end_ns: int) -> Iterator[Record]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(
            starting_at=start_ns, ending_at=end_ns, log_time_order=True
        ):
            if schema is not None:
                yield _record(schema, channel, message)


@dataclass(frozen=True)
class Snapshot:
    """A file as it was at one moment: read again later it gives the same messages, as
    files only grow (an export that reads twice, the bag's, relies on it)."""

    path: Path
    finished: bool
    size: int


def snapshot(f: RecordingFile) -> Snapshot:
    return Snapshot(f.path, finished(f.path), f.size)


def snapshot_messages(taken: Snapshot, start_ns: int, end_ns: int) -> Iterator[Record]:
    """The messages of ``taken`` in ``[start_ns, end_ns]``, as ``open_messages`` read them
    when the snapshot was taken: by the index if finished then, else up to its size then."""
    if taken.finished:
        yield from _indexed(taken.path, start_ns, end_ns)
    else:
        yield from _streamed(taken.path, start_ns, end_ns, taken.size)


class _Capped:
    """A binary file read no further than ``limit`` bytes."""

    def __init__(self, f: IO[bytes], limit: int) -> None:
        self.f, self.left = f, limit

    def read(self, size: int = -1) -> bytes:
        size = self.left if size < 0 else min(size, self.left)
        data = self.f.read(size)
        self.left -= len(data)
        return data


def _streamed(path: Path, start_ns: int, end_ns: int, limit: int | None = None) -> Iterator[Record]:
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    with open(path, "rb") as f:
        stream: IO[bytes] = f if limit is None else _Capped(f, limit)  # type: ignore[assignment]
        try:
            for item in StreamReader(stream, skip_magic=False).records:
                if isinstance(item, Schema):
                    schemas[item.id] = item
                elif isinstance(item, Channel):
                    channels[item.id] = item
                elif isinstance(item, Message) and start_ns <= item.log_time <= end_ns:
                    channel = channels.get(item.channel_id)
                    schema = schemas.get(channel.schema_id) if channel else None
                    if channel is not None and schema is not None:
                        yield _record(schema, channel, item)
        except (McapError, EOFError, ValueError, struct.error):
            return  # the file was cut short here: what came before stands


def _record(schema: Schema, channel: Channel, message: Message) -> Record:
    return Record(channel.topic, schema.name, schema.data, message.log_time, message.data)


def repair(path: Path) -> None:
    """Rewrite an unfinished file with its summary (what a stop mid-file left behind)."""
    partial = path.with_suffix(".repairing")
    with open(partial, "wb") as out:
        sink = McapSink(out)
        for record in _streamed(path, 0, 2**63 - 1):
            sink.add(record)
        sink.finish()
    os.replace(partial, path)


def repair_all(root: Path) -> int:
    """Repair every unfinished file under ``root`` that no live writer holds (what a
    stopped or killed process left); return how many."""
    if not root.is_dir():
        return 0
    return sum(_repair_directory(directory) for directory in root.iterdir())


def repair_robot(root: Path, robot: str) -> int:
    """Repair the robot's unfinished files that no live writer holds (see ``repair_all``);
    return how many."""
    return _repair_directory(robot_dir(root, robot))


def _repair_directory(directory: Path) -> int:
    count = 0
    for path in directory.glob(f"*{SUFFIX}") if directory.is_dir() else []:
        if not finished(path) and _repair_if_closed(path):
            count += 1
    return count


def _repair_if_closed(path: Path) -> bool:
    with claimed(path) as closed:
        # finished meanwhile: its writer closed it between the two looks
        if closed and not finished(path):
            repair(path)
            return True
    return False
