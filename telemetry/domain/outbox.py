"""A connection's bounded send queue: when the socket cannot keep up, the oldest frame goes.

Frames wait here only while the socket is not writable; a subscriber that stops reading
therefore costs at most ``max_frames`` frames and ``max_bytes`` bytes of memory, and the
publisher's fan-out never waits for it.
"""

from __future__ import annotations

from collections import deque

from .encoding import Wire


class Outbox:
    """FIFO of encoded messages bounded by count and by bytes, dropping from the head."""

    __slots__ = ("_bytes", "_queue", "dropped", "max_bytes", "max_frames")

    def __init__(self, max_frames: int, max_bytes: int) -> None:
        self.max_frames = max_frames
        self.max_bytes = max_bytes
        self._queue: deque[Wire] = deque()
        self._bytes = 0
        self.dropped = 0

    def __len__(self) -> int:
        return len(self._queue)

    @property
    def nbytes(self) -> int:
        return self._bytes

    def push(self, wire: Wire) -> None:
        """Append ``wire``, then drop the oldest frames until both bounds hold again.

        The newest frame always stays, even if it alone is over ``max_bytes``.
        """
        self._queue.append(wire)
        self._bytes += wire.nbytes
        while len(self._queue) > 1 and (
            len(self._queue) > self.max_frames or self._bytes > self.max_bytes
        ):
            self._bytes -= self._queue.popleft().nbytes
            self.dropped += 1

    def pop(self) -> Wire | None:
        """Remove and return the oldest frame, or None when empty."""
        if not self._queue:
            return None
        wire = self._queue.popleft()
        self._bytes -= wire.nbytes
        return wire

    def clear(self) -> None:
        self._queue.clear()
        self._bytes = 0
