"""ROS 1 bags (format 2.0) written front to back, for streaming an export as it is made.

A bag's header names where its index starts, which is known only when every chunk is
written; a writer that seeks back (``rosbags``') needs a file. Here the messages are
read twice instead: the first pass lays the chunks out and keeps only three numbers (the
index position, the connection and chunk counts), the second yields the bag, one
uncompressed chunk at a time, then the connections and the chunk index. Memory is one
chunk, whatever the range. The two passes must read the same messages: the caller gives
a ``source`` that yields the same sequence each time it is called, and a difference is
raised as ``BagSourceChanged`` rather than written as a broken bag.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Protocol

from . import ros1

MAGIC = b"#ROSBAG V2.0\n"
HEADER_RECORD_BYTES = 4096
CHUNK_BYTES = 1024 * 1024
_OP_MESSAGE, _OP_BAG, _OP_INDEX, _OP_CHUNK, _OP_CHUNK_INFO, _OP_CONNECTION = (
    b"\x02",
    b"\x03",
    b"\x04",
    b"\x05",
    b"\x06",
    b"\x07",
)
_U32 = struct.Struct("<I").pack
_U64 = struct.Struct("<Q").pack
_TIME = struct.Struct("<II").pack
_INDEX_ENTRY = struct.Struct("<III").pack
_NS = 1_000_000_000


class BagRecord(Protocol):
    """One message to write: its topic, ROS 1 type and definition, time (ns) and bytes."""

    @property
    def topic(self) -> str: ...
    @property
    def type_name(self) -> str: ...
    @property
    def schema(self) -> bytes: ...
    @property
    def log_time(self) -> int: ...
    @property
    def data(self) -> bytes: ...


class BagSourceChanged(RuntimeError):
    """The second reading of the messages differed from the first."""


def bag_stream(
    source: Callable[[], Iterable[BagRecord]], chunk_bytes: int = CHUNK_BYTES
) -> Iterator[bytes]:
    """The bag of ``source()``'s messages, in pieces (one chunk and its index each).
    Raises BagSourceChanged when the second pass does not match the first."""
    plan = _Layout(chunk_bytes)
    for _chunk in plan.chunks(source()):
        pass
    yield MAGIC + _bag_header(plan.end, len(plan.connections), plan.chunk_count)
    layout = _Layout(chunk_bytes)
    yield from layout.chunks(source())
    if (layout.end, layout.connections, layout.chunk_count) != (
        plan.end,
        plan.connections,
        plan.chunk_count,
    ):
        raise BagSourceChanged("the messages changed between the two readings")
    yield b"".join(_connection_record(c) for c in layout.connections.values())
    yield b"".join(layout.chunk_infos)


@dataclass(frozen=True)
class _Connection:
    id: int
    topic: str
    type_name: str
    schema: bytes


@dataclass
class _Chunk:
    """The chunk being filled: its bytes and, per connection, its messages' times and
    offsets."""

    data: bytearray = field(default_factory=bytearray)
    index: dict[int, list[bytes]] = field(default_factory=dict)
    start: int = 0
    end: int = 0


class _Layout:
    """Chunks of a message sequence, their positions in the bag and the index they need."""

    def __init__(self, chunk_bytes: int) -> None:
        self.chunk_bytes = chunk_bytes
        self.connections: dict[str, _Connection] = {}
        self.chunk_infos: list[bytes] = []
        self.end = len(MAGIC) + HEADER_RECORD_BYTES  # where the next chunk goes

    @property
    def chunk_count(self) -> int:
        return len(self.chunk_infos)

    def chunks(self, records: Iterable[BagRecord]) -> Iterator[bytes]:
        """Each chunk record with its index records, as written."""
        chunk = _Chunk()
        for record in records:
            self._add(chunk, record)
            if len(chunk.data) >= self.chunk_bytes:
                yield self._close(chunk)
                chunk = _Chunk()
        if chunk.data:
            yield self._close(chunk)

    def _add(self, chunk: _Chunk, record: BagRecord) -> None:
        connection = self.connections.get(record.topic)
        if connection is None:
            connection = _Connection(
                len(self.connections), record.topic, record.type_name, record.schema
            )
            self.connections[record.topic] = connection
            chunk.data += _connection_record(connection)
        stamp = _TIME(*divmod(record.log_time, _NS))
        if not chunk.index:
            chunk.start = record.log_time
        chunk.start, chunk.end = min(chunk.start, record.log_time), max(chunk.end, record.log_time)
        chunk.index.setdefault(connection.id, []).append(stamp + _U32(len(chunk.data)))
        fields = [(b"op", _OP_MESSAGE), (b"conn", _U32(connection.id)), (b"time", stamp)]
        chunk.data += _record(fields, record.data)

    def _close(self, chunk: _Chunk) -> bytes:
        fields = [(b"op", _OP_CHUNK), (b"compression", b"none"), (b"size", _U32(len(chunk.data)))]
        written = [_record(fields, bytes(chunk.data))]
        for conn, entries in sorted(chunk.index.items()):
            index_fields = [
                (b"op", _OP_INDEX),
                (b"ver", _U32(1)),
                (b"conn", _U32(conn)),
                (b"count", _U32(len(entries))),
            ]
            written.append(_record(index_fields, b"".join(entries)))
        info_fields = [
            (b"op", _OP_CHUNK_INFO),
            (b"ver", _U32(1)),
            (b"chunk_pos", _U64(self.end)),
            (b"start_time", _TIME(*divmod(chunk.start, _NS))),
            (b"end_time", _TIME(*divmod(chunk.end, _NS))),
            (b"count", _U32(len(chunk.index))),
        ]
        counts = b"".join(_U32(c) + _U32(len(e)) for c, e in sorted(chunk.index.items()))
        self.chunk_infos.append(_record(info_fields, counts))
        out = b"".join(written)
        self.end += len(out)
        return out


def _header(fields: list[tuple[bytes, bytes]]) -> bytes:
    return b"".join(
        _U32(len(name) + 1 + len(value)) + name + b"=" + value for name, value in fields
    )


def _record(fields: list[tuple[bytes, bytes]], data: bytes) -> bytes:
    header = _header(fields)
    return _U32(len(header)) + header + _U32(len(data)) + data


def _bag_header(index_pos: int, connections: int, chunks: int) -> bytes:
    fields = [
        (b"op", _OP_BAG),
        (b"index_pos", _U64(index_pos)),
        (b"conn_count", _U32(connections)),
        (b"chunk_count", _U32(chunks)),
    ]
    header = _header(fields)
    padding = HEADER_RECORD_BYTES - 4 - len(header) - 4
    return _U32(len(header)) + header + _U32(padding) + b" " * padding


def _connection_record(connection: _Connection) -> bytes:
    name = ros1.ros1_name(connection.type_name)
    described = [
        (b"topic", connection.topic.encode()),
        (b"type", name.encode()),
        (b"md5sum", ros1.md5sum(name).encode()),
        (b"message_definition", connection.schema),
    ]
    fields = [
        (b"op", _OP_CONNECTION),
        (b"conn", _U32(connection.id)),
        (b"topic", connection.topic.encode()),
    ]
    return _record(fields, _header(described))
