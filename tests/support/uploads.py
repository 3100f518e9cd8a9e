"""Requests to a live server over plain HTTP, signed in with HTTP Basic."""

from __future__ import annotations

import base64
import http.client

from tests.fixtures_live import LiveServer


def basic(user: str) -> dict[str, str]:
    pair = base64.b64encode(f"{user}:pw-{user}".encode()).decode()
    return {"Authorization": f"Basic {pair}"}


def request(
    server: LiveServer, method: str, path: str, body: bytes = b"", headers: dict | None = None
) -> tuple[int, dict[str, str], bytes]:
    connection = http.client.HTTPConnection(server.host, server.port, timeout=30)
    try:
        connection.request(method, path, body=body, headers=headers or {})
        answer = connection.getresponse()
        return answer.status, dict(answer.getheaders()), answer.read()
    finally:
        connection.close()
