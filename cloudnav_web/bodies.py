"""Request bodies are taken only from those who may send them, and only up to a limit.

daphne reads a request's whole body, then hands all of it to the application's queue at
once, before any view or authentication runs: an anonymous client could make the server
hold any number of large bodies. ``GatedRequest`` takes daphne's place for HTTP requests
(``install``) and decides from the headers, before the body is kept anywhere:

- no body may pass ``CLOUDNAV_MAX_BODY_BYTES``: a larger declared length is refused (413)
  and its bytes are read and dropped as they come;
- a body larger than ``CLOUDNAV_ANONYMOUS_BODY_BYTES`` (or of unknown length) needs
  credentials: a request without a session cookie or an ``Authorization`` header is
  refused (401) the same way. One that has them waits, its body in Twisted's temporary
  file on disk, until the credentials are checked (a signed-in session, a robot's token,
  HTTP Basic); only then does daphne read it into memory for the application.

Small anonymous bodies (the sign-in form) pass as before.
"""

from __future__ import annotations

import asyncio
import base64
import binascii
import json
from collections.abc import Mapping
from http.cookies import SimpleCookie
from importlib import import_module
from typing import Any

from channels.db import database_sync_to_async
from django.conf import settings
from django.contrib.auth import SESSION_KEY, authenticate
from django.contrib.sessions.backends.base import SessionBase
from django.http import HttpRequest
from twisted.internet.defer import Deferred, inlineCallbacks
from twisted.web import http

from robots.services import robot_for_token

Refusal = tuple[int, bytes, str]  # status, reason phrase, detail


def refusal_for(length: int | None, headers: Mapping[bytes, bytes]) -> Refusal | None:
    """Return why a body of ``length`` bytes (None: unknown) must be refused, from the
    headers alone, or None if it may come (perhaps after its credentials are checked)."""
    largest = settings.CLOUDNAV_MAX_BODY_BYTES
    if length is not None and length > largest:
        return 413, b"Content Too Large", f"A request body may be at most {largest} bytes."
    if needs_credentials(length) and not (
        b"authorization" in headers
        or settings.SESSION_COOKIE_NAME.encode() in headers.get(b"cookie", b"")
    ):
        return _UNAUTHORISED
    return None


def needs_credentials(length: int | None) -> bool:
    return length is None or length > settings.CLOUDNAV_ANONYMOUS_BODY_BYTES


_UNAUTHORISED: Refusal = (
    401,
    b"Unauthorized",
    "Sign in, or send a token, to send a body this large.",
)


async def credentials_hold(headers: Mapping[bytes, bytes], client: str = "") -> bool:
    """True if the request carries credentials that hold: a signed-in session, a robot's
    token, or a user's HTTP Basic name and password (from ``client``'s address)."""
    return bool(await database_sync_to_async(_credentials_hold)(dict(headers), client))


def _credentials_hold(headers: dict[bytes, bytes], client: str = "") -> bool:
    authorization = headers.get(b"authorization", b"").decode("latin-1").split()
    if len(authorization) == 2:
        return _authorization_holds(authorization[0].lower(), authorization[1], client)
    cookie = SimpleCookie(headers.get(b"cookie", b"").decode("latin-1"))
    morsel = cookie.get(settings.SESSION_COOKIE_NAME)
    return morsel is not None and _session_holds(morsel.value)


def _authorization_holds(scheme: str, credentials: str, client: str) -> bool:
    if scheme == "token":
        return robot_for_token(credentials) is not None
    if scheme == "basic":
        try:
            username, _, password = base64.b64decode(credentials).decode("utf-8").partition(":")
        except (binascii.Error, ValueError):
            return False
        # A sign-in like any other: counted, and refused while locked out (settings, axes).
        return authenticate(_sign_in(client), username=username, password=password) is not None
    return False


def _sign_in(client: str) -> HttpRequest:
    """The request that a sign-in's rate limit counts: made from ``client``'s address."""
    request = HttpRequest()
    request.method = "POST"
    request.META["REMOTE_ADDR"] = client
    return request


def _session_holds(key: str) -> bool:
    store: SessionBase = import_module(settings.SESSION_ENGINE).SessionStore(key)
    return store.get(SESSION_KEY) is not None


def install() -> None:
    """Make daphne build its HTTP requests as ``GatedRequest`` (no-op without daphne).

    daphne's factory names its request class when it builds each connection, so this
    takes effect for every connection accepted afterwards.
    """
    try:
        from daphne import http_protocol
    except ImportError:
        return
    if not issubclass(http_protocol.WebRequest, _Gated):
        http_protocol.WebRequest = _gated(http_protocol.WebRequest)


class _Gated:
    """Marks the gated request class."""


def _gated(base: type[http.Request]) -> type[http.Request]:
    class GatedRequest(base, _Gated):  # type: ignore[valid-type,misc]
        """daphne's request, deciding on its body before keeping it (see the module)."""

        refusal: Refusal | None = None
        received = 0

        def gotLength(self, length: int | None) -> None:
            self.refusal = refusal_for(length, _headers(self))
            # A refused body is read and dropped: nothing keeps it.
            super().gotLength(0 if self.refusal else length)

        def handleContentChunk(self, data: bytes) -> None:
            self.received += len(data)
            if self.refusal is None and self.received > settings.CLOUDNAV_MAX_BODY_BYTES:
                self.refusal = refusal_for(self.received, {})
                self.content.seek(0)
                self.content.truncate()
            if self.refusal is None:
                super().handleContentChunk(data)

        @inlineCallbacks
        def process(self) -> Any:
            if self.refusal is None and needs_credentials(self.received):
                client = getattr(self.getClientAddress(), "host", "")
                check = asyncio.ensure_future(credentials_hold(_headers(self), client))
                if not (yield Deferred.fromFuture(check)):
                    self.refusal = _UNAUTHORISED
            if self.refusal is None:
                yield super().process()
            else:
                self._refuse(self.refusal)

        def _refuse(self, refusal: Refusal) -> None:
            status, phrase, detail = refusal
            body = json.dumps({"detail": detail}).encode()
            self.setResponseCode(status, phrase)
            self.setHeader(b"content-type", b"application/json")
            self.setHeader(b"content-length", b"%d" % len(body))
            if status == 401:
                self.setHeader(b"www-authenticate", b'Token, Basic realm="api"')
            self.write(body)
            http.Request.finish(self)  # not daphne's: no application was started for it

        def connectionLost(self, reason: Any) -> None:
            if self.refusal is None:
                super().connectionLost(reason)
            else:
                http.Request.connectionLost(self, reason)

    return GatedRequest


def _headers(request: Any) -> dict[bytes, bytes]:
    return {
        name.lower(): b", ".join(values)
        for name, values in request.requestHeaders.getAllRawHeaders()
    }
