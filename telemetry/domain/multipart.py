"""web_video_server's MJPEG wire format: a ``multipart/x-mixed-replace`` body.

The body opens with ``--boundarydonotcross`` and each image is one part::

    Content-type: image/jpeg\\r\\n
    X-Timestamp: 1712345678.123456\\r\\n
    Content-Length: 23456\\r\\n
    \\r\\n
    <the image bytes>\\r\\n
    --boundarydonotcross\\r\\n

so a part is complete, boundary included, as soon as it is written: a browser shows it at
once instead of waiting for the next one. The headers every response carries, and those of
a single snapshot, are built here too.
"""

from __future__ import annotations

BOUNDARY = "boundarydonotcross"
CONTENT_TYPE = f"multipart/x-mixed-replace;boundary={BOUNDARY}"
_DELIMITER = f"--{BOUNDARY}\r\n".encode("ascii")
_FOOTER = b"\r\n" + _DELIMITER

NO_CACHE = "no-cache, no-store, must-revalidate, pre-check=0, post-check=0, max-age=0"
SERVER = "web_video_server"


def preamble() -> bytes:
    """Return what the body starts with, before the first part."""
    return _DELIMITER


def x_timestamp(seconds: float) -> str:
    """Return a time as web_video_server writes it: seconds with six decimals."""
    return f"{seconds:.6f}"


def part(payload: bytes, content_type: str, stamp: float) -> bytes:
    """Return one image as a complete part, closing boundary included."""
    head = (
        f"Content-type: {content_type}\r\n"
        f"X-Timestamp: {x_timestamp(stamp)}\r\n"
        f"Content-Length: {len(payload)}\r\n\r\n"
    ).encode("ascii")
    return b"".join((head, payload, _FOOTER))


def stream_headers(content_type: str = CONTENT_TYPE) -> dict[str, str]:
    """Return the headers of an endless stream response (MJPEG, or ``video/webm``)."""
    return {
        "Content-Type": content_type,
        "Server": SERVER,
        "Cache-Control": NO_CACHE,
        "Pragma": "no-cache",
        "Access-Control-Allow-Origin": "*",
    }


def video_headers(content_type: str) -> dict[str, str]:
    """Return the headers of a libav (VP8) stream: the stream's, and no expiry at all."""
    return {**stream_headers(content_type), "Expires": "0", "Max-Age": "0"}


def snapshot_headers(content_type: str, stamp: float, length: int) -> dict[str, str]:
    """Return the headers of a single image (``/snapshot``)."""
    return {
        **stream_headers(content_type),
        "X-Timestamp": x_timestamp(stamp),
        "Content-Length": str(length),
    }


class PartReader:
    """Reads a multipart body as it arrives (the client side, for tests and benchmarks).

    ``feed`` returns the parts completed by the new bytes, each as its headers (names in
    lower case) and payload. Raises ValueError when the body does not follow the format.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._started = False

    def feed(self, data: bytes) -> list[tuple[dict[str, str], bytes]]:
        self._buffer += data
        if not self._started:
            if len(self._buffer) < len(_DELIMITER):
                return []
            if not self._buffer.startswith(_DELIMITER):
                raise ValueError("the body does not start with the boundary")
            del self._buffer[: len(_DELIMITER)]
            self._started = True
        parts = []
        while (found := self._next_part()) is not None:
            parts.append(found)
        return parts

    def _next_part(self) -> tuple[dict[str, str], bytes] | None:
        end = self._buffer.find(b"\r\n\r\n")
        if end < 0:
            return None
        headers = {}
        for line in self._buffer[:end].decode("ascii").split("\r\n"):
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
        length = int(headers["content-length"])
        total = end + 4 + length + len(_FOOTER)
        if len(self._buffer) < total:
            return None
        payload = bytes(self._buffer[end + 4 : end + 4 + length])
        if self._buffer[end + 4 + length : total] != _FOOTER:
            raise ValueError("a part does not end with the boundary")
        del self._buffer[:total]
        return headers, payload
