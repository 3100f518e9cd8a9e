"""Services and actions that clients advertise, and the requests waiting for their answers.

As in rosbridge_suite, a client advertises a name; a request from another client goes to
it as ``call_service`` (or ``send_action_goal``) with an id of its own,
``service_request:{name}:{n}`` (``action_goal:{name}:{n}``), ``n`` counting from 1 for each
advertisement; the provider answers with that id and the answer is routed back to the
caller under the caller's id. Advertising a name again replaces the provider; the requests
still waiting on the old one fail.

A peer advertises at most ``limits.services`` names in one table and has at most
``limits.pending_calls`` requests waiting there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .bus import Peer
from .limits import ConnectionLimits, check_room
from .protocol import Json


@dataclass(slots=True)
class PendingCall:
    """A request forwarded to a provider, waiting for its answer."""

    name: str
    caller: Peer
    caller_id: Json
    request_id: str
    caller_spelling: str = ""
    fragment_size: int | None = None
    compression: str = "none"
    feedback: bool = False


@dataclass(slots=True)
class Provider:
    """The client serving one advertised name, and the requests it has not answered yet."""

    name: str
    type: str
    peer: Peer
    spelling: str = ""
    counter: int = 0
    pending: dict[str, PendingCall] = field(default_factory=dict)


class CallTable:
    """Advertised names of one kind (services or actions) and their pending requests.

    ``id_prefix`` is ``service_request`` or ``action_goal``.
    """

    def __init__(self, id_prefix: str, limits: ConnectionLimits | None = None) -> None:
        self.id_prefix = id_prefix
        self.limits = limits or ConnectionLimits()
        self._providers: dict[str, Provider] = {}
        # per peer key: names it serves, requests it waits on
        self._served: dict[str, int] = {}
        self._waiting: dict[str, int] = {}
        # (caller key, caller id) -> (name, request id), to cancel or drop a caller's calls
        self._by_caller: dict[tuple[str, Json], tuple[str, str]] = {}

    def provider(self, name: str) -> Provider | None:
        return self._providers.get(name)

    def names(self) -> list[tuple[str, str]]:
        """Return ``(name, type)`` of every advertised name."""
        return [(p.name, p.type) for p in self._providers.values()]

    def served_by(self, peer: Peer) -> list[Provider]:
        """Return the names ``peer`` provides."""
        return [p for p in self._providers.values() if p.peer.key == peer.key]

    def advertise(
        self, name: str, type_name: str, peer: Peer, spelling: str | None = None
    ) -> list[PendingCall]:
        """Make ``peer`` the provider of ``name``; return the old provider's orphaned calls.

        ``spelling`` is the name as the provider wrote it: its requests carry that name.
        """
        current = self._providers.get(name)
        if current is None or current.peer.key != peer.key:
            check_room("advertised names", self._served.get(peer.key, 0), self.limits.services)
        orphans = self._retire(name)
        self._providers[name] = Provider(name, type_name, peer, spelling or name)
        self._served[peer.key] = self._served.get(peer.key, 0) + 1
        return orphans

    def unadvertise(self, name: str, peer: Peer) -> list[PendingCall] | None:
        """Withdraw ``peer``'s advertisement; None if it is not the provider of ``name``."""
        provider = self._providers.get(name)
        if provider is None or provider.peer.key != peer.key:
            return None
        return self._retire(name)

    def _retire(self, name: str) -> list[PendingCall]:
        provider = self._providers.pop(name, None)
        if provider is None:
            return []
        _decrement(self._served, provider.peer.key)
        for call in provider.pending.values():
            self._by_caller.pop((call.caller.key, call.caller_id), None)
            _decrement(self._waiting, call.caller.key)
        return list(provider.pending.values())

    def start(
        self,
        provider: Provider,
        caller: Peer,
        caller_id: Json,
        caller_spelling: str | None = None,
        fragment_size: int | None = None,
        compression: str = "none",
        feedback: bool = False,
    ) -> PendingCall:
        """Record a request to ``provider`` and return it with the id the provider will see.

        Raises LimitReached when ``caller`` already waits on as many requests as it may.
        """
        waiting = self._waiting.get(caller.key, 0)
        check_room("requests waiting for an answer", waiting, self.limits.pending_calls)
        self._waiting[caller.key] = waiting + 1
        provider.counter += 1
        request_id = f"{self.id_prefix}:{provider.spelling}:{provider.counter}"
        call = PendingCall(
            provider.name,
            caller,
            caller_id,
            request_id,
            caller_spelling or provider.name,
            fragment_size,
            compression,
            feedback,
        )
        provider.pending[request_id] = call
        if caller_id is not None:
            self._by_caller[(caller.key, caller_id)] = (provider.name, request_id)
        return call

    def find(self, name: str, peer: Peer, request_id: Json) -> PendingCall | None:
        """Return the pending request ``request_id`` if ``peer`` is the one serving it."""
        provider = self._providers.get(name)
        if provider is None or provider.peer.key != peer.key:
            return None
        return provider.pending.get(request_id) if isinstance(request_id, str) else None

    def finish(self, name: str, peer: Peer, request_id: Json) -> PendingCall | None:
        """Remove and return the request ``peer`` just answered, or None if unknown."""
        call = self.find(name, peer, request_id)
        if call is not None:
            provider = self._providers[name]
            del provider.pending[call.request_id]
            self._by_caller.pop((call.caller.key, call.caller_id), None)
            _decrement(self._waiting, call.caller.key)
        return call

    def of_caller(self, caller: Peer, caller_id: Json) -> tuple[Provider, PendingCall] | None:
        """Return the provider and request that ``caller`` started under ``caller_id``."""
        where = self._by_caller.get((caller.key, caller_id))
        if where is None:
            return None
        provider = self._providers.get(where[0])
        call = provider.pending.get(where[1]) if provider else None
        return (provider, call) if provider and call else None

    def drop(self, peer: Peer) -> list[PendingCall]:
        """Forget ``peer`` as provider and as caller; return the calls left without provider."""
        orphans: list[PendingCall] = []
        for name in [n for n, p in self._providers.items() if p.peer.key == peer.key]:
            orphans.extend(self._retire(name))
        for provider in self._providers.values():
            for request_id in [r for r, c in provider.pending.items() if c.caller.key == peer.key]:
                call = provider.pending.pop(request_id)
                self._by_caller.pop((peer.key, call.caller_id), None)
        self._waiting.pop(peer.key, None)
        return [call for call in orphans if call.caller.key != peer.key]


def _decrement(counts: dict[str, int], key: str) -> None:
    left = counts.get(key, 0) - 1
    if left > 0:
        counts[key] = left
    else:
        counts.pop(key, None)
