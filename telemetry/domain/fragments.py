"""rosbridge ``fragment`` frames: splitting outgoing JSON and reassembling incoming pieces.

A fragmented message is its JSON text cut into ``data`` pieces of at most ``fragment_size``
characters; ``num`` counts from 0 and ``total`` is an integer (rosbridge_suite itself sends
a float there, which strict clients reject).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from telemetry.exceptions import BadFrame, LimitReached

from .limits import ByteBudget
from .protocol import FragmentFrame
from .timers import Cancellable, Scheduler


def split(text: str, size: int, fragment_id: Any) -> list[FragmentFrame]:
    """Return the fragments of ``text``; a text that fits in ``size`` still gives one piece."""
    total = max(1, -(-len(text) // size))
    return [
        FragmentFrame(
            op="fragment", id=fragment_id, data=text[i * size : (i + 1) * size], num=i, total=total
        )
        for i in range(total)
    ]


# What a stored piece costs beside its characters (the str and dict entry), so that a
# flood of one-character pieces counts for what it holds.
PIECE_OVERHEAD = 64


@dataclass
class _Pending:
    total: int
    pieces: dict[int, str] = field(default_factory=dict)
    cost: int = 0
    timer: Cancellable | None = None


class Reassembler:
    """Collects one connection's incoming fragments until a message is whole.

    Bounded four ways: the pieces this connection holds cost at most ``max_bytes``
    (and at most ``max_pending`` messages are in progress); the connections of one person
    or robot draw on their ``client_share``; every connection's pieces together draw on
    the ``shared`` budget; and a message that got no piece for
    ``timeout`` seconds is forgotten by a timer, whether or not anything else arrives.
    """

    def __init__(
        self,
        max_bytes: int,
        shared: ByteBudget,
        scheduler: Scheduler,
        timeout: float = 10.0,
        max_pending: int = 16,
        client_share: ByteBudget | None = None,
    ) -> None:
        self.max_bytes = max_bytes
        self.shared = shared
        self.client_share = client_share or ByteBudget(max_bytes)
        self.scheduler = scheduler
        self.timeout = timeout
        self.max_pending = max_pending
        self.held = 0
        self._pending: dict[Any, _Pending] = {}

    def add(self, fragment_id: Any, num: int, total: int, data: str) -> str | None:
        """Store one piece; return the whole message text once every piece has arrived.

        Raises BadFrame for a piece that contradicts the others, LimitReached when this
        connection's or the server's budget is spent; the message it belonged to is then
        forgotten.
        """
        pending = self._pending_for(fragment_id, total)
        if not 0 <= num < total or total != pending.total or num in pending.pieces:
            self._forget(fragment_id)
            raise BadFrame(f"fragment {num} of {total} does not fit message {fragment_id!r}")
        self._hold(fragment_id, pending, data)
        pending.pieces[num] = data
        if len(pending.pieces) < total:
            self._arm(fragment_id, pending)
            return None
        self._forget(fragment_id)
        return "".join(pending.pieces[i] for i in range(total))

    def clear(self) -> None:
        """Forget every message in progress (the connection closed)."""
        for fragment_id in list(self._pending):
            self._forget(fragment_id)

    def _pending_for(self, fragment_id: Any, total: int) -> _Pending:
        pending = self._pending.get(fragment_id)
        if pending is None:
            if total < 1:
                raise BadFrame("fragment total must be at least 1")
            if len(self._pending) >= self.max_pending:
                raise LimitReached("too many fragmented messages in progress")
            pending = self._pending[fragment_id] = _Pending(total=total)
        return pending

    def _hold(self, fragment_id: Any, pending: _Pending, data: str) -> None:
        # A str of ASCII takes a byte per character, any other up to four.
        cost = PIECE_OVERHEAD + len(data) * (1 if data.isascii() else 4)
        try:
            if self.held + cost > self.max_bytes:
                raise LimitReached(
                    f"fragmented messages of this connection are over {self.max_bytes} bytes"
                )
            self.client_share.take(cost, "fragmented messages for all this client's connections")
            try:
                self.shared.take(cost, "fragmented messages")
            except LimitReached:
                self.client_share.give_back(cost)
                raise
        except LimitReached:
            self._forget(fragment_id)
            raise
        pending.cost += cost
        self.held += cost

    def _arm(self, fragment_id: Any, pending: _Pending) -> None:
        if pending.timer is not None:
            pending.timer.cancel()
        pending.timer = self.scheduler(self.timeout, lambda: self._forget(fragment_id))

    def _forget(self, fragment_id: Any) -> None:
        pending = self._pending.pop(fragment_id, None)
        if pending is None:
            return
        if pending.timer is not None:
            pending.timer.cancel()
        self.held -= pending.cost
        self.shared.give_back(pending.cost)
        self.client_share.give_back(pending.cost)
