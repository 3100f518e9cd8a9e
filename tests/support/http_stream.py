"""A viewer of the HTTP video streams (``/stream``): the client side, for tests and benchmarks.

It speaks HTTP/1.0 over a plain socket, as web_video_server's viewers do, so a test or a
benchmark sees the bytes exactly as the server sends them; read the body with
``multipart.PartReader`` (MJPEG) or ``tests.support.webm_reader.WebmReader`` (VP8).
"""

from __future__ import annotations

import asyncio
import socket
import urllib.parse
from dataclasses import dataclass


@dataclass
class Stream:
    """An open HTTP response: its status, headers (lower-case names) and body reader."""

    status: int
    headers: dict[str, str]
    reader: asyncio.StreamReader
    writer: asyncio.StreamWriter

    def close(self) -> None:
        self.writer.close()


async def open_stream(
    base_url: str,
    path: str,
    cookie: str | None = None,
    token: str | None = None,
    receive_buffer: int | None = None,
) -> Stream:
    """GET ``path`` over HTTP/1.0 and return once the response headers are in.

    ``token`` goes in an ``Authorization: Token`` header; ``receive_buffer`` shrinks the
    socket's receive buffer (to play a slow viewer). Raises OSError if it cannot connect.
    """
    parts = urllib.parse.urlsplit(base_url)
    host, port = parts.hostname or "127.0.0.1", parts.port or 80
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if receive_buffer is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
    sock.setblocking(False)
    await asyncio.get_running_loop().sock_connect(sock, (host, port))
    reader, writer = await asyncio.open_connection(sock=sock, limit=2**22)
    lines = [f"GET {path} HTTP/1.0", f"Host: {host}:{port}"]
    lines += [f"Cookie: {cookie}"] if cookie else []
    lines += [f"Authorization: Token {token}"] if token else []
    writer.write(("\r\n".join(lines) + "\r\n\r\n").encode("latin-1"))
    status, headers = response_head(await reader.readuntil(b"\r\n\r\n"))
    return Stream(status, headers, reader, writer)


def response_head(head: bytes) -> tuple[int, dict[str, str]]:
    """Return the status and the headers (lower-case names) of a response's head."""
    status_line, *header_lines = head.decode("latin-1").split("\r\n")
    headers = {}
    for header in filter(None, header_lines):
        name, _, value = header.partition(":")
        headers[name.strip().lower()] = value.strip()
    return int(status_line.split()[1]), headers
