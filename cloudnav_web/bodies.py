"""Request bodies are taken only from those who may send them, and only up to a limit.

Django reads a request's whole body (into memory up to ``FILE_UPLOAD_MAX_MEMORY_SIZE``)
before any view or authentication runs, so ``BodyGate`` sits in front of it:

- a body larger than ``CLOUDNAV_ANONYMOUS_BODY_BYTES`` (or of unknown length) needs
  credentials that hold (a session of a signed-in user, a robot token, or HTTP Basic); a
  request without them is answered 401 before a byte of its body is read;
- no body may pass ``CLOUDNAV_MAX_BODY_BYTES``: a larger declared length is answered 413
  at once, and a body that turns out larger than it declared is cut off.

Small anonymous bodies (the sign-in form) pass as before. Under daphne the server itself
has spooled the body to a temporary file before any application code runs (in memory
below 100 kB, on disk above); the gate keeps it from reaching memory in Django.
"""

from __future__ import annotations

import base64
import binascii
import json
from collections.abc import Awaitable, Callable, Mapping
from http.cookies import SimpleCookie
from importlib import import_module
from typing import Any

from channels.db import database_sync_to_async
from django.conf import settings
from django.contrib.auth import SESSION_KEY, authenticate
from django.contrib.sessions.backends.base import SessionBase

from robots.services import robot_for_token

Scope = dict[str, Any]
Receive = Callable[[], Awaitable[dict[str, Any]]]
Send = Callable[[dict[str, Any]], Awaitable[None]]


class BodyGate:
    """ASGI middleware for HTTP: see the module's docstring."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = _headers(scope)
        length = _declared_length(headers)
        largest = settings.CLOUDNAV_MAX_BODY_BYTES
        if length is not None and length > largest:
            await _answer(send, 413, f"A request body may be at most {largest} bytes.")
            return
        if (length is None or length > settings.CLOUDNAV_ANONYMOUS_BODY_BYTES) and not (
            await has_credentials(headers)
        ):
            await _answer(send, 401, "Sign in, or send a token, to send a body this large.")
            return
        await self.app(scope, _bounded(receive, largest), send)


def _headers(scope: Scope) -> dict[bytes, bytes]:
    return {name.lower(): value for name, value in scope.get("headers", [])}


def _declared_length(headers: Mapping[bytes, bytes]) -> int | None:
    """Return the body's declared length: 0 when there is none, None when unknown."""
    if b"transfer-encoding" in headers:
        return None
    value = headers.get(b"content-length", b"0")
    return int(value) if value.isdigit() else None


def _bounded(receive: Receive, largest: int) -> Receive:
    """Return ``receive`` that ends the request (as a disconnect) past ``largest`` bytes."""
    taken = 0

    async def bounded() -> dict[str, Any]:
        nonlocal taken
        message = await receive()
        if message["type"] == "http.request":
            taken += len(message.get("body", b""))
            if taken > largest:
                return {"type": "http.disconnect"}
        return message

    return bounded


async def _answer(send: Send, status: int, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", b"%d" % len(body))]
    if status == 401:
        headers.append((b"www-authenticate", b'Token, Basic realm="api"'))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


async def has_credentials(headers: Mapping[bytes, bytes]) -> bool:
    """True if the request carries credentials that hold: a signed-in session, a robot's
    token, or a user's HTTP Basic name and password."""
    return bool(await database_sync_to_async(_credentials_hold)(dict(headers)))


def _credentials_hold(headers: dict[bytes, bytes]) -> bool:
    authorization = headers.get(b"authorization", b"").decode("latin-1").split()
    if len(authorization) == 2:
        return _authorization_holds(authorization[0].lower(), authorization[1])
    cookie = SimpleCookie(headers.get(b"cookie", b"").decode("latin-1"))
    morsel = cookie.get(settings.SESSION_COOKIE_NAME)
    return morsel is not None and _session_holds(morsel.value)


def _authorization_holds(scheme: str, credentials: str) -> bool:
    if scheme == "token":
        return robot_for_token(credentials) is not None
    if scheme == "basic":
        try:
            username, _, password = base64.b64decode(credentials).decode("utf-8").partition(":")
        except (binascii.Error, ValueError):
            return False
        return authenticate(username=username, password=password) is not None
    return False


def _session_holds(key: str) -> bool:
    store: SessionBase = import_module(settings.SESSION_ENGINE).SessionStore(key)
    return store.get(SESSION_KEY) is not None
