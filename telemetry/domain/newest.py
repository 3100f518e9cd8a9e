"""The newest value of something that changes, for many asyncio readers that never queue.

A writer ``put``s values; each reader remembers the version it last took and waits for a
newer one. Readers that are slower than the writer see fewer versions (they skip), and
memory holds one value whatever the number of readers: the relay keeps one camera frame
per topic and one encoded image per stream this way.
"""

from __future__ import annotations

import asyncio
from typing import Generic, TypeVar

T = TypeVar("T")


class Closed(Exception):
    """The value will not change any more (its source stopped)."""


class Newest(Generic[T]):
    """One value and its version, which counts the ``put`` calls (0: nothing yet)."""

    def __init__(self) -> None:
        self.version = 0
        self.value: T | None = None
        self.closed = False
        self._changed = asyncio.Event()

    def put(self, value: T) -> None:
        """Replace the value and wake every reader waiting for a newer one."""
        self.value = value
        self.version += 1
        self._wake()

    def close(self) -> None:
        """End the value's life: waiting readers (and later ones) get Closed."""
        self.closed = True
        self._wake()

    def _wake(self) -> None:
        # Each change sets the current event and starts a new one, so a reader that waits
        # after this change waits for the next, and none misses one.
        changed, self._changed = self._changed, asyncio.Event()
        changed.set()

    async def newer(self, version: int) -> tuple[int, T]:
        """Return ``(version, value)`` as soon as the version is above ``version``.

        Raises Closed once the value is closed.
        """
        while self.version <= version and not self.closed:
            await self._changed.wait()
        if self.closed:
            raise Closed()
        assert self.value is not None  # a version above 0 means a value was put
        return self.version, self.value
