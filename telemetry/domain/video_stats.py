"""Statistics of one video stream over a sliding window, the figures of Table I.

For each stream: frames per second and kilobytes per second of what one viewer receives,
the delay from each frame's ``header.stamp`` to the moment it is written to a viewer
(p50 and p99), how long the relay itself held it (from arrival to send), the encoder's
share of a CPU core, and the frames viewers skipped because they read slowly.

Memory is bounded: events older than the window are dropped as new ones come, and the
delay samples are capped.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

WINDOW = 5.0
MAX_SAMPLES = 20_000
# Frames that arrive this much later (or earlier) than their stamps, at the median, are
# stamped by a clock other than the server's (a robot's, offset or scaled): their
# stamp-to-sent delays measure that offset, not the stream, and are not given as delays.
CLOCK_SKEW_S = 5.0


def percentile(values: Iterable[float], p: float) -> float | None:
    """Return the nearest-rank ``p``-th percentile (0-100), or None for no values."""
    ordered = sorted(values)
    if not ordered:
        return None
    rank = max(1, math.ceil(p / 100 * len(ordered)))
    return ordered[min(rank, len(ordered)) - 1]


@dataclass
class Series:
    """Timestamped amounts over the last ``window`` seconds."""

    window: float = WINDOW
    events: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=MAX_SAMPLES))

    def add(self, now: float, amount: float) -> None:
        self.events.append((now, amount))
        self.prune(now)

    def prune(self, now: float) -> None:
        while self.events and self.events[0][0] < now - self.window:
            self.events.popleft()

    def per_second(self, now: float, since: float) -> float:
        """Return the amount per second over the window, or since ``since`` if later."""
        self.prune(now)
        span = min(self.window, now - since)
        return sum(amount for _, amount in self.events) / span if span > 0 else 0.0

    def values(self, now: float) -> list[float]:
        self.prune(now)
        return [amount for _, amount in self.events]


@dataclass
class StreamStats:
    """The counters of one stream since ``started``; ``snapshot`` turns them into the
    published figures."""

    started: float
    frames_in: Series = field(default_factory=Series)
    bytes_out: Series = field(default_factory=Series)
    delays: Series = field(default_factory=Series)
    relay_delays: Series = field(default_factory=Series)
    arrivals: Series = field(default_factory=Series)  # arrival minus stamp, seconds
    cpu: Series = field(default_factory=Series)
    frames_sent: int = 0
    frames_skipped: int = 0
    bytes_sent: int = 0

    def produced(self, now: float, nbytes: int) -> None:
        """The stream produced one frame of ``nbytes`` (what each viewer is sent)."""
        self.frames_in.add(now, 1)
        self.bytes_out.add(now, nbytes)

    def encoded(self, now: float, cpu_seconds: float) -> None:
        """The encoder spent ``cpu_seconds`` of CPU on one frame."""
        self.cpu.add(now, cpu_seconds)

    def sent(self, now: float, times: Iterable[tuple[float, float]], nbytes: int) -> None:
        """Frames were written to a viewer in ``nbytes``; ``times`` holds the stamp and the
        arrival time of each of them."""
        self.bytes_sent += nbytes
        for origin, received in times:
            self.frames_sent += 1
            self.delays.add(now, now - origin)
            self.relay_delays.add(now, now - received)
            self.arrivals.add(now, received - origin)

    def skipped(self, count: int) -> None:
        self.frames_skipped += count

    def snapshot(self, now: float) -> dict[str, float | int | None]:
        """Return the figures: rates over the window, delays in ms, totals since start.
        ``clock_offset_ms`` is how far the stamps' clock is behind the server's when it is
        off by more than CLOCK_SKEW_S (the stamp delays are None then), else None."""
        delays = self.delays.values(now)
        relay = self.relay_delays.values(now)
        arrival = percentile(self.arrivals.values(now), 50)
        offset = arrival if arrival is not None and abs(arrival) > CLOCK_SKEW_S else None
        if offset is not None:
            delays = []
        # The first figures are those a narrow UI shows: keep them first.
        return {
            "fps": round(self.frames_in.per_second(now, self.started), 2),
            "kB_per_s": round(self.bytes_out.per_second(now, self.started) / 1000, 2),
            "delay_p50_ms": _ms(percentile(delays, 50)),
            "delay_p99_ms": _ms(percentile(delays, 99)),
            "relay_p99_ms": _ms(percentile(relay, 99)),
            "clock_offset_ms": _ms(offset),
            "encoder_cpu": round(self.cpu.per_second(now, self.started), 4),
            "frames_sent": self.frames_sent,
            "frames_skipped": self.frames_skipped,
            "sent_kB": round(self.bytes_sent / 1000, 1),
        }


def _ms(seconds: float | None) -> float | None:
    return None if seconds is None else round(seconds * 1000, 1)
