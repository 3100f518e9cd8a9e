"""ROS times in both spellings: ROS 2's ``sec/nanosec`` and ROS 1's ``secs/nsecs``.

Clients of either generation talk to one server, so every time the server reads accepts
both, and every time it writes carries both (roslibpy reads ``secs``, roslib reads ``sec``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

from cloudnav_core.messages import NANOS, Time, ros_time


def parse_stamp(value: Mapping[str, Any]) -> tuple[int, int]:
    """Return ``(sec, nanosec)`` from a time in either spelling.

    Raises ValueError when neither spelling is present or the numbers are not integers.
    """
    for sec_key, nsec_key in (("sec", "nanosec"), ("secs", "nsecs")):
        if sec_key in value:
            sec, nsec = value[sec_key], value.get(nsec_key, 0)
            if not _is_int(sec) or not _is_int(nsec):
                raise ValueError(f"time fields must be integers, got {sec!r}, {nsec!r}")
            return normalise(int(sec), int(nsec))
    raise ValueError("a time needs sec/nanosec or secs/nsecs")


def stamp_seconds(msg: Mapping[str, Any]) -> float | None:
    """Return ``header.stamp`` (``timestamp`` in a ``CompressedVideo``) in seconds, or None
    if the message has none (or a zero one)."""
    header = msg.get("header")
    value = header.get("stamp") if isinstance(header, Mapping) else msg.get("timestamp")
    if not isinstance(value, Mapping):
        return None
    try:
        sec, nanosec = parse_stamp(value)
    except ValueError:
        return None
    return sec + nanosec / NANOS if (sec or nanosec) else None


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def normalise(sec: int, nanosec: int) -> tuple[int, int]:
    """Carry whole seconds out of ``nanosec`` so that 0 <= nanosec < 1e9."""
    extra, nanosec = divmod(nanosec, NANOS)
    return sec + extra, nanosec


def stamp(sec: int, nanosec: int) -> Time:
    """Return a time that readers of either spelling understand."""
    return {"sec": sec, "nanosec": nanosec, "secs": sec, "nsecs": nanosec}


def now_stamp(clock: Any = time.time) -> Time:
    """Return the current wall-clock time in both spellings."""
    now = ros_time(clock())
    return stamp(now["sec"], now["nanosec"])


def complete_header_stamp(msg: dict[str, Any]) -> None:
    """Give a message's ``header.stamp`` both spellings, in place, if it has one of them.

    A ROS 1-style publisher (``secs``) and a ROS 2-style subscriber (``sec``) then
    understand each other. Only the top-level header is touched: that is the stamp every
    client reads, and looking no deeper keeps this O(1) on the publish path.
    """
    header = msg.get("header")
    stamp_value = header.get("stamp") if isinstance(header, dict) else None
    if not isinstance(stamp_value, dict) or len(stamp_value) > 2:
        return
    try:
        sec, nanosec = parse_stamp(stamp_value)
    except ValueError:
        return
    stamp_value.update(stamp(sec, nanosec))


SILENT_S = 30.0
"""Seconds of the server's clock a robot may stay silent before ``RobotClocks`` takes its
clock to run on at the server's pace."""


class RobotClocks:
    """Each robot's own time, as the stamps of its messages tell it, as a ROS node's timers
    run on ``/clock`` under ``use_sim_time``: a simulated robot running at a quarter of real
    time has a quarter of the server's seconds. ``heard`` reads a stamped message; ``now``
    is the last stamp heard, standing still between messages, then running on at
    ``clock``'s pace once the robot has said nothing for ``SILENT_S``."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._read: dict[str, tuple[float, float]] = {}  # robot -> (its time, ours then)

    def heard(self, robot: str, msg: Mapping[str, Any]) -> None:
        """``robot`` published ``msg``: its header's stamp, if it has one, is its time now."""
        said = stamp_seconds(msg)
        if said is not None:
            self._read[robot] = (said, self._clock())

    def now(self, robot: str) -> float | None:
        """``robot``'s time now, None if it never said."""
        read = self._read.get(robot)
        if read is None:
            return None
        said, heard_at = read
        return said + max(0.0, self._clock() - heard_at - SILENT_S)
