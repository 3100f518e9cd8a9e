"""What one rosbridge connection may make the server hold, and byte budgets shared by all.

Counts are per connection, so one client cannot crowd out the others: subscription
requests, advertised topics, advertised services and actions, calls waiting for an answer,
parameters it set and their bytes, the bytes of the latched messages it published, and
the bytes of its fragmented messages in progress.
"""

from __future__ import annotations

from dataclasses import dataclass

from telemetry.exceptions import LimitReached


@dataclass(frozen=True, slots=True)
class ConnectionLimits:
    subscriptions: int = 1024
    advertisements: int = 256
    services: int = 256
    pending_calls: int = 1024
    params: int = 256
    param_bytes: int = 4 * 2**20
    fragment_bytes: int = 4 * 2**20
    min_fragment_size: int = 1024
    latched_bytes: int = 16 * 2**20


def check_room(what: str, held: int, limit: int) -> None:
    """Raise LimitReached if a connection holding ``held`` of ``what`` may not take one more."""
    if held >= limit:
        raise LimitReached(f"this connection already holds {limit} {what}, the most it may")


class ByteBudget:
    """Bytes that many holders draw on together, such as every connection's fragments."""

    __slots__ = ("limit", "used")

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.used = 0

    def take(self, size: int, what: str) -> None:
        """Reserve ``size`` bytes. Raises LimitReached if that would pass the limit."""
        if self.used + size > self.limit:
            raise LimitReached(f"the server holds {self.limit} bytes of {what}, the most it may")
        self.used += size

    def give_back(self, size: int) -> None:
        self.used = max(0, self.used - size)


class Holdings:
    """Named things that each holder keeps, with their sizes: at most ``max_count`` names and
    ``max_bytes`` bytes per holder (the parameters each connection set, for instance)."""

    def __init__(self, what: str, max_count: int, max_bytes: int) -> None:
        self.what = what
        self.max_count = max_count
        self.max_bytes = max_bytes
        self._held: dict[str, dict[str, int]] = {}

    def take(self, holder: str, name: str, size: int) -> None:
        """Record that ``holder`` keeps ``name`` of ``size`` bytes (replacing what it kept
        under that name). Raises LimitReached if that passes the holder's count or bytes."""
        held = self._held.get(holder, {})
        if name not in held:
            check_room(self.what, len(held), self.max_count)
        if sum(held.values()) - held.get(name, 0) + size > self.max_bytes:
            raise LimitReached(
                f"this connection's {self.what} would pass {self.max_bytes} bytes, the most it may"
            )
        held[name] = size
        self._held[holder] = held

    def release(self, holder: str, name: str) -> None:
        held = self._held.get(holder)
        if held is not None:
            held.pop(name, None)

    def drop(self, holder: str) -> list[str]:
        """Forget ``holder``; return the names it kept."""
        return list(self._held.pop(holder, {}))
