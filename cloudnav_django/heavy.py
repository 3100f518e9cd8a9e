"""Heavy HTTP work within a budget: beyond it, a quick 429 or 503 instead of gigabytes.

Some answers cost far more than others: a building's tag sheet (A4 pages at 300 dpi), the
``/grid`` of a large map (a JSON list of millions of cells), a tag printed at its true
size, a video encoder at the largest parameters. Each such request first takes a ticket
for the memory it will need (an estimate from what it was asked) from the process-wide
``HeavyBudget``; the ticket is given back once the answer has been sent, since the body
stays in memory until then. Under daphne the answer is written at the pace its client reads
(``cloudnav_django.readiness``), since daphne would otherwise take it all at once and hold
it in Twisted's buffer out of the budget's sight. A request the budget cannot take at once
is answered at once:

- 429 Too Many Requests when the same client already has ``per_client`` heavy requests
  in progress (its own share is spent);
- 503 Service Unavailable when the process as a whole is at its ``slots`` or ``memory``;

both with ``Retry-After``. Nothing waits in a queue, so waiting requests hold no memory. A
request that alone needs more than the whole budget is answered 503 without Retry-After.
"""

from __future__ import annotations

import threading
import weakref
from collections import Counter
from collections.abc import AsyncIterator, Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from asgiref.sync import sync_to_async
from django.conf import settings
from django.http import HttpResponse, HttpResponseBase, StreamingHttpResponse
from rest_framework import status
from rest_framework.exceptions import APIException

from cloudnav_django.readiness import readiness_for

RETRY_AFTER = 2  # seconds: heavy answers take about that long
CHUNK = 256 * 2**10  # bytes written at a time when pacing an answer to its client


class Overloaded(APIException):
    """The heavy-work budget cannot take this request now; ``wait`` becomes Retry-After."""

    status_code: int = status.HTTP_503_SERVICE_UNAVAILABLE
    default_detail = "The server is busy with other heavy requests; try again shortly."
    default_code = "overloaded"

    def __init__(self, detail: str, status_code: int, wait: int | None = RETRY_AFTER) -> None:
        super().__init__(detail)
        self.status_code = status_code
        self.wait = wait


@dataclass
class Ticket:
    """Memory and a slot taken from a budget, until ``release``."""

    budget: HeavyBudget
    client: str
    need: int
    released: bool = False

    def release(self) -> None:
        self.budget.give_back(self)

    def handover(self) -> Ticket | None:
        """Return a ticket for the same share to a new holder (this one then releases
        nothing), or None if this one was released already."""
        return self.budget.hand_over(self)


@dataclass
class HeavyBudget:
    """At most ``slots`` heavy requests at once, ``memory`` bytes (estimated) among them,
    and ``per_client`` of them for any one client. Thread-safe: sync views run in threads."""

    slots: int
    memory: int
    per_client: int
    used_memory: int = 0
    _clients: Counter[str] = field(default_factory=Counter)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def take(self, client: str, need: int) -> Ticket:
        """Return a ticket for ``need`` bytes. Raises Overloaded (429 or 503) if the budget
        cannot take it now."""
        if need > self.memory:
            raise Overloaded(
                f"This answer needs about {need // 2**20} MiB, more than the server's budget "
                f"for heavy answers ({self.memory // 2**20} MiB).",
                status.HTTP_503_SERVICE_UNAVAILABLE,
                wait=None,
            )
        with self._lock:
            if self._clients[client] >= self.per_client:
                raise Overloaded(
                    "You have other heavy requests in progress; try again when they are done.",
                    status.HTTP_429_TOO_MANY_REQUESTS,
                )
            if sum(self._clients.values()) >= self.slots or self.used_memory + need > self.memory:
                raise Overloaded(Overloaded.default_detail, status.HTTP_503_SERVICE_UNAVAILABLE)
            self._clients[client] += 1
            self.used_memory += need
        return Ticket(self, client, need)

    def hand_over(self, ticket: Ticket) -> Ticket | None:
        with self._lock:
            if ticket.released:
                return None
            ticket.released = True
            return Ticket(self, ticket.client, ticket.need)

    def give_back(self, ticket: Ticket) -> None:
        with self._lock:
            if ticket.released:
                return
            ticket.released = True
            self.used_memory -= ticket.need
            self._clients[ticket.client] -= 1
            if self._clients[ticket.client] <= 0:
                del self._clients[ticket.client]

    @property
    def in_progress(self) -> int:
        return sum(self._clients.values())


_budgets: dict[tuple[str, int, int, int], HeavyBudget] = {}
_budgets_lock = threading.Lock()


def heavy_budget() -> HeavyBudget:
    """Return this process's budget of heavy answers, made from the settings on first use."""
    return _budget("CLOUDNAV_HEAVY")


def video_budget() -> HeavyBudget:
    """Return this process's budget of video encoders (each held while it is watched)."""
    return _budget("CLOUDNAV_VIDEO_ENCODER")


def export_budget() -> HeavyBudget:
    """Return this process's budget of recording exports (each held until it is sent)."""
    return _budget("CLOUDNAV_EXPORT")


def _budget(prefix: str) -> HeavyBudget:
    # Keyed by the settings too, so a test that changes them gets a budget of its own.
    key = (
        prefix,
        getattr(settings, f"{prefix}_SLOTS"),
        getattr(settings, f"{prefix}_MEMORY_BYTES"),
        getattr(settings, f"{prefix}_PER_CLIENT"),
    )
    with _budgets_lock:
        budget = _budgets.get(key)
        if budget is None:
            budget = _budgets[key] = HeavyBudget(slots=key[1], memory=key[2], per_client=key[3])
        return budget


def client_of(request: Any) -> str:
    """Return who is asking: the signed-in user or robot, else the peer address."""
    user = getattr(request, "user", None)
    if user is not None and user.is_authenticated:
        return f"user:{user.username}"
    return f"addr:{request.META.get('REMOTE_ADDR', '')}"


def release_with(response: HttpResponseBase, ticket: Ticket) -> None:
    """Give ``ticket`` back once ``response`` is done: sent and closed, or dropped.

    Django closes a response it has sent, but not one whose client went away meanwhile
    (the task sending it is cancelled); the response is then dropped, which releases too.
    """
    # Django calls these on close (the list is how it closes a FileResponse's file too).
    response._resource_closers.append(ticket.release)  # type: ignore[attr-defined]
    weakref.finalize(response, ticket.release)


def heavy_response(
    request: Any, need: int, build: Callable[[], bytes], content_type: str
) -> HttpResponseBase:
    """Answer with the body ``build`` makes, within the heavy-work budget.

    ``need`` estimates the bytes the work and its answer hold; the ticket is held until
    the answer has left (under daphne, until the client has taken it). Raises Overloaded
    when the budget cannot take it now (DRF answers 429 or 503 with Retry-After).
    """
    ticket = heavy_budget().take(client_of(request), need)
    try:
        body = build()
    except BaseException:
        ticket.release()
        raise
    scope = getattr(getattr(request, "_request", request), "scope", None)
    response: HttpResponseBase
    if scope is None:  # not served over ASGI: the server's own write paces it
        response = HttpResponse(body, content_type=content_type)
    else:
        response = StreamingHttpResponse(_paced(body, scope, ticket), content_type=content_type)
        response["Content-Length"] = str(len(body))
    release_with(response, ticket)
    return response


def budgeted_stream(
    request: Any, ticket: Ticket, chunks: Iterator[bytes], content_type: str
) -> StreamingHttpResponse:
    """Answer with ``chunks`` as they are made, holding ``ticket`` until the answer is done.

    Under ASGI each chunk is made in a worker thread once the client took the one before,
    so the answer never waits whole in memory (Django would read a plain iterator to its
    end first) nor in Twisted's buffer.
    """
    scope = getattr(getattr(request, "_request", request), "scope", None)
    content = _releasing(chunks, ticket) if scope is None else _paced_chunks(chunks, scope, ticket)
    response = StreamingHttpResponse(content, content_type=content_type)
    release_with(response, ticket)
    return response


def _releasing(chunks: Iterator[bytes], ticket: Ticket) -> Iterator[bytes]:
    try:
        yield from chunks
    finally:
        ticket.release()


_DONE = object()


def _next_chunk(chunks: Iterator[bytes]) -> object:
    return next(chunks, _DONE)


async def _paced_chunks(
    chunks: Iterator[bytes], scope: Mapping[str, Any], ticket: Ticket
) -> AsyncIterator[bytes]:
    """Yield ``chunks``, each made (in a thread: it reads files) once the client took the
    one before."""
    readiness = readiness_for(scope)  # here, on the event loop, where Twisted runs
    made = sync_to_async(_next_chunk, thread_sensitive=False)
    try:
        while (chunk := await made(chunks)) is not _DONE:
            await readiness.wait()
            yield chunk  # type: ignore[misc]
    finally:
        readiness.close()
        ticket.release()
        close = getattr(chunks, "close", None)
        if close is not None:
            await sync_to_async(close, thread_sensitive=False)()


async def _paced(body: bytes, scope: Mapping[str, Any], ticket: Ticket) -> AsyncIterator[bytes]:
    """Yield ``body`` a chunk at a time, each once the client took the one before."""
    readiness = readiness_for(scope)  # here, on the event loop, where Twisted runs
    try:
        for start in range(0, len(body), CHUNK):
            await readiness.wait()
            yield body[start : start + CHUNK]
    finally:
        readiness.close()
        ticket.release()
