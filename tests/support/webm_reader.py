"""A live WebM body read as it arrives: the viewer's side of ``telemetry.domain.webm``, for
tests and benchmarks."""

from __future__ import annotations

from dataclasses import dataclass

from telemetry.domain.webm import (
    BLOCK,
    BLOCK_DURATION,
    BLOCK_GROUP,
    CLUSTER,
    DATE_UTC,
    INFO,
    KEYFRAME_FLAG,
    MATROSKA_EPOCH,
    REFERENCE_BLOCK,
    SEGMENT,
    SIMPLE_BLOCK,
    TIMESTAMP,
)


@dataclass(frozen=True, slots=True)
class Block:
    """One frame as a viewer reads it: Cluster time (ms), keyframe flag, VP8 bytes and the
    declared duration (ms; None for a SimpleBlock, which has none)."""

    timestamp: int
    keyframe: bool
    data: bytes
    duration: int | None = None


def _vint(buffer: bytes | bytearray, at: int, keep_marker: bool) -> tuple[int, int] | None:
    """Return ``(value, length)`` of the EBML variable-length integer at ``at``, or None
    if the buffer ends first. Sizes of all ones (unknown) come back as -1."""
    if at >= len(buffer):
        return None
    first = buffer[at]
    length = 9 - first.bit_length() if first else 9
    if length > 8:
        raise ValueError("not an EBML variable-length integer")
    if at + length > len(buffer):
        return None
    value = int.from_bytes(buffer[at : at + length], "big")
    if keep_marker:
        return value, length
    value &= (1 << (7 * length)) - 1
    return (-1 if value == (1 << (7 * length)) - 1 else value), length


class WebmReader:
    """Reads a live WebM body as it arrives (the client side, for tests and benchmarks).

    ``feed`` returns the Blocks completed by the new bytes; ``epoch`` is the Segment's
    DateUTC (Unix seconds) once the init segment was read. Raises ValueError on bytes that
    are not EBML.
    """

    _CONTAINERS = frozenset({SEGMENT})

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.epoch: float | None = None
        self.clusters = 0

    def feed(self, data: bytes) -> list[Block]:
        self._buffer += data
        blocks: list[Block] = []
        while (element_ := self._next_element()) is not None:
            element_id, payload = element_
            if element_id == INFO:
                self._read_info(payload)
            elif element_id == CLUSTER:
                self.clusters += 1
                blocks.extend(self._read_cluster(payload))
        return blocks

    def _next_element(self) -> tuple[bytes, bytes] | None:
        """Take the next complete top-level element (entering the Segment) off the buffer."""
        while True:
            header = self._header(self._buffer, 0)
            if header is None:
                return None
            element_id, size, start = header
            if element_id in self._CONTAINERS:
                del self._buffer[:start]  # its children follow, read them one by one
                continue
            if size < 0:
                raise ValueError("only the Segment may have an unknown size")
            if len(self._buffer) < start + size:
                return None
            payload = bytes(self._buffer[start : start + size])
            del self._buffer[: start + size]
            return element_id, payload

    @staticmethod
    def _header(buffer: bytes | bytearray, at: int) -> tuple[bytes, int, int] | None:
        """Return the ID, size and payload start of the element at ``at``, or None."""
        found_id = _vint(buffer, at, keep_marker=True)
        if found_id is None:
            return None
        found_size = _vint(buffer, at + found_id[1], keep_marker=False)
        if found_size is None:
            return None
        element_id = bytes(buffer[at : at + found_id[1]])
        return element_id, found_size[0], at + found_id[1] + found_size[1]

    def _children(self, payload: bytes) -> list[tuple[bytes, bytes]]:
        children, at = [], 0
        while at < len(payload):
            header = self._header(payload, at)
            if header is None:
                raise ValueError("an element ends inside a child's header")
            element_id, size, start = header
            children.append((element_id, payload[start : start + size]))
            at = start + size
        return children

    def _read_info(self, payload: bytes) -> None:
        for element_id, value in self._children(payload):
            if element_id == DATE_UTC:
                nanoseconds = int.from_bytes(value, "big", signed=True)
                self.epoch = MATROSKA_EPOCH + nanoseconds / 1e9

    def _read_cluster(self, payload: bytes) -> list[Block]:
        timestamp, blocks = 0, []
        for element_id, value in self._children(payload):
            if element_id == TIMESTAMP:
                timestamp = int.from_bytes(value, "big")
            elif element_id == SIMPLE_BLOCK:
                relative, flags, data = _block(value)
                blocks.append(Block(timestamp + relative, bool(flags & KEYFRAME_FLAG), data))
            elif element_id == BLOCK_GROUP:
                blocks.append(self._read_group(timestamp, value))
        return blocks

    def _read_group(self, timestamp: int, payload: bytes) -> Block:
        """A BlockGroup: a keyframe unless it references another block."""
        children = dict(self._children(payload))
        if BLOCK not in children:
            raise ValueError("a BlockGroup without a Block")
        relative, _, data = _block(children[BLOCK])
        duration = children.get(BLOCK_DURATION)
        return Block(
            timestamp + relative,
            REFERENCE_BLOCK not in children,
            data,
            None if duration is None else int.from_bytes(duration, "big"),
        )


def _block(value: bytes) -> tuple[int, int, bytes]:
    """``(relative timestamp, flags, frame)`` of a Block or SimpleBlock body."""
    track = _vint(value, 0, keep_marker=False)
    if track is None or len(value) < track[1] + 3:
        raise ValueError("a block too short for its header")
    offset = track[1]
    relative = int.from_bytes(value[offset : offset + 2], "big", signed=True)
    return relative, value[offset + 2], value[offset + 3 :]
