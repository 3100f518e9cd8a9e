"""Timers as the domain takes them: the shape of asyncio's ``loop.call_later``, so the
bus and the fragment reassembler run on an event loop or on a test's clock alike."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol


class Cancellable(Protocol):
    def cancel(self) -> None: ...


# call_later(delay_seconds, callback) -> a handle that can be cancelled (asyncio's signature)
Scheduler = Callable[[float, Callable[[], None]], Cancellable]
