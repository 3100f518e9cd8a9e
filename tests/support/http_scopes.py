"""HTTP requests through the real ASGI application, without a server: the scope and a GET
that reads a stream up to its first bytes."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlencode

from asgiref.testing import ApplicationCommunicator

WAIT = 5.0


@dataclass
class Answer:
    status: int
    headers: dict[str, str]
    body: bytes

    def json(self) -> Any:
        return json.loads(self.body)


def http_scope(path: str, query: dict[str, str], headers: dict[str, str]) -> dict[str, Any]:
    return {
        "type": "http",
        "http_version": "1.1",
        "method": "GET",
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "root_path": "",
        "query_string": urlencode(query).encode(),
        "headers": [(b"host", b"testserver")]
        + [(k.lower().encode(), v.encode()) for k, v in headers.items()],
        "client": ("127.0.0.1", 50000),
        "server": ("testserver", 80),
    }


async def get(path: str, query: dict[str, str], headers: dict[str, str] | None = None) -> Answer:
    """GET through the ASGI application; a stream is read up to its first body bytes and
    then abandoned, as a client that goes away."""
    from cloudnav_web.asgi import application

    app = ApplicationCommunicator(application, http_scope(path, query, headers or {}))
    await app.send_input({"type": "http.request", "body": b"", "more_body": False})
    start = await app.receive_output(WAIT)
    headers_in = {k.decode().lower(): v.decode() for k, v in start["headers"]}
    answer = Answer(start["status"], headers_in, b"")
    streaming = "content-length" not in answer.headers and answer.status == 200
    while not streaming:
        message = await app.receive_output(WAIT)
        answer.body += message.get("body", b"")
        if not message.get("more_body"):
            break
    await app.send_input({"type": "http.disconnect"})
    await app.wait(WAIT)
    return answer
