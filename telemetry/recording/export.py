"""Any time range of one or several robots as one MCAP file (or ROS 1 bag), written as it
is read.

``mcap_stream`` and ``bag_stream`` yield the file in pieces as its chunks fill, so an hour
or a month of recording is never held in memory: at most one chunk of output and one of
input.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from telemetry.domain import ros1, rosbag
from telemetry.domain.events import EVENTS_TOPIC

from . import files

EXPORT_CHUNK_BYTES = 1024 * 1024
# What one export holds while it is sent, whatever its range (the export budget's unit):
# chunks of output being filled and taken, input being read, the readers. Measured with
# tracemalloc: a peak of 8.1 MiB for a 160 MiB export of 1 MiB images, .mcap or .bag
# (tests/test_hostile_exports.py); twice that leaves room for larger messages.
EXPORT_MEMORY_BYTES = 16 * EXPORT_CHUNK_BYTES


class _Pipe:
    """A write-only stream whose bytes are taken out as they come (``take``)."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._written = 0

    def write(self, data: bytes) -> int:
        self._buffer += data
        self._written += len(data)
        return len(data)

    def tell(self) -> int:
        return self._written

    def take(self) -> bytes:
        data = bytes(self._buffer)
        self._buffer.clear()
        return data


def records(
    root: Path, robots: Iterable[str], start_ns: int, end_ns: int
) -> Iterator[files.Record]:
    """The robots' messages in ``[start_ns, end_ns]``, merged in time order."""
    return snapshot_records(snapshot(root, robots, start_ns, end_ns), start_ns, end_ns)


Snapshots = list[list[files.Snapshot]]


def snapshot(root: Path, robots: Iterable[str], start_ns: int, end_ns: int) -> Snapshots:
    """Each robot's files that may hold messages in the range, as they are now."""
    return [
        [files.snapshot(f) for f in files.files_between(root, robot, start_ns, end_ns)]
        for robot in sorted(set(robots))
    ]


def snapshot_records(taken: Snapshots, start_ns: int, end_ns: int) -> Iterator[files.Record]:
    """The messages of ``taken`` in the range, merged in time order; the same each time."""
    streams = [_robot_records(robot_files, start_ns, end_ns) for robot_files in taken]
    return heapq.merge(*streams, key=lambda r: r.log_time)


def _robot_records(
    robot_files: list[files.Snapshot], start_ns: int, end_ns: int
) -> Iterator[files.Record]:
    for f in robot_files:
        yield from files.snapshot_messages(f, start_ns, end_ns)


def without_events(source: Iterable[files.Record]) -> Iterator[files.Record]:
    """``source`` less the events the server derived (``/{robot}/events``): they name the
    people who drove, stopped or sent goals, which a robot reading its own recording does
    not learn."""
    return (r for r in source if r.topic.split("/", 2)[-1] != EVENTS_TOPIC)


def mcap_stream(source: Iterable[files.Record]) -> Iterator[bytes]:
    """One MCAP file (ROS 1 profile) of ``source``, yielded in pieces as it is written.
    With no record it is a valid, empty MCAP file."""
    pipe = _Pipe()
    sink = files.McapSink(pipe, chunk_size=EXPORT_CHUNK_BYTES)  # type: ignore[arg-type]
    for record in source:
        sink.add(record)
        if len(pipe._buffer) >= EXPORT_CHUNK_BYTES:
            yield pipe.take()
    sink.finish()
    yield pipe.take()


def bag_stream(source: Callable[[], Iterable[files.Record]]) -> Iterator[bytes]:
    """A ROS 1 bag of ``source()``'s messages, yielded as it is written (``rosbag``: two
    readings of ``source``, which must give the same messages, as a snapshot's do)."""
    return rosbag.bag_stream(source, EXPORT_CHUNK_BYTES)


def json_window(
    source: Iterable[files.Record], topics: set[str] | None, limit: int
) -> dict[str, Any]:
    """At most ``limit`` messages of ``source`` (of ``topics``' suffixes when given) as
    rosbridge JSON for a page replaying the recording; ``more`` says the window was cut."""
    messages: list[dict[str, Any]] = []
    for record in source:
        suffix = record.topic.split("/", 2)[-1]
        if topics is not None and suffix not in topics:
            continue
        if len(messages) >= limit:
            return {"messages": messages, "more": True, "next": record.log_time / 1e9}
        msg = ros1.to_json(ros1.decode(record.type_name, record.data))
        messages.append({"t": record.log_time / 1e9, "topic": record.topic, "msg": msg})
    return {"messages": messages, "more": False, "next": None}


def span(root: Path, robot: str) -> tuple[float, float] | None:
    """The times (seconds) of the robot's first and last recorded messages (the last
    file's last write while it is being written); None without files."""
    found = files.files_of(root, robot)
    if not found:
        return None
    return found[0].start_ns / 1e9, files.end_of(found[-1]) / 1e9
