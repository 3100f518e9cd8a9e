"""Outgoing frames encoded once per variant, however many connections receive them.

A variant is a ``(compression, fragment_size)`` pair: ``none`` gives JSON text frames (cut
into ``fragment`` frames past ``fragment_size``), ``cbor`` one binary CBOR frame. ``Wire``
keeps the payloads and, on demand, the same bytes framed as RFC 6455 server frames; server
frames are unmasked, so those bytes are identical for every connection and can be written
to each socket as they are.

Byte strings (``uint8[]`` from a CBOR publisher) become base64 in JSON, as rosbridge's JSON
writes ``uint8[]``. A string holding a lone surrogate (JSON's ``"\\ud800"`` decodes to
one) cannot be UTF-8: JSON then escapes it as it came, CBOR replaces it with U+FFFD. Both
happen only when the plain encoding fails, so the common path pays nothing for them.

Nothing here bounds the size of what it encodes: the frames it is given are bounded where
they come from (``decoding`` refuses anything past the node budget, so no structure shares
parts), and each connection refuses to send an encoding past its own limit.
"""

from __future__ import annotations

import base64
import itertools
import json
import math
import struct
from typing import Any

import cbor2

from .fragments import split
from .protocol import OutFrame

_fragment_ids = itertools.count(1)

Variant = tuple[str, int | None, str | None]
"""How one subscriber receives a message: ``(compression, fragment_size, topic spelling)``."""


def _base64(value: Any) -> str:
    if isinstance(value, bytes | bytearray | memoryview):
        return base64.b64encode(value).decode("ascii")
    raise TypeError(f"{type(value).__name__} has no JSON form")


_dumps = json.JSONEncoder(
    separators=(",", ":"), allow_nan=False, ensure_ascii=False, default=_base64
).encode
_dumps_ascii = json.JSONEncoder(separators=(",", ":"), allow_nan=False, default=_base64).encode


def to_json(value: Any) -> str:
    """Return compact JSON; NaN and infinities become ``null`` as in rosbridge's JSON, and
    byte strings base64."""
    try:
        return _dumps(value)
    except ValueError:
        return _dumps(_without_nan(value))


def _utf8(text: str) -> bytes:
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError:  # a lone surrogate: the ASCII spelling escapes it
        return _dumps_ascii(_without_nan(json.loads(text))).encode("ascii")


def _cbor(frame: Any) -> bytes:
    try:
        return cbor2.dumps(frame)
    except UnicodeEncodeError:
        return cbor2.dumps(_without_surrogates(frame))


def _without_surrogates(value: Any) -> Any:
    if isinstance(value, str):
        return value.encode("utf-16", "surrogatepass").decode("utf-16", "replace")
    if isinstance(value, dict):
        return {_without_surrogates(k): _without_surrogates(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_without_surrogates(v) for v in value]
    return value


def _without_nan(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _without_nan(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_without_nan(v) for v in value]
    return value


def ws_frame(payload: bytes, binary: bool) -> bytes:
    """Return ``payload`` as one final, unmasked WebSocket data frame (RFC 6455 section 5.2)."""
    first = 0x82 if binary else 0x81
    size = len(payload)
    if size < 126:
        header = bytes((first, size))
    elif size < 65536:
        header = struct.pack("!BBH", first, 126, size)
    else:
        header = struct.pack("!BBQ", first, 127, size)
    return header + payload


class Wire:
    """One message encoded for one variant: its frame payloads, in order."""

    __slots__ = ("_framed", "binary", "nbytes", "payloads")

    def __init__(self, payloads: tuple[bytes, ...], binary: bool) -> None:
        self.payloads = payloads
        self.binary = binary
        self.nbytes = sum(len(p) for p in payloads)
        self._framed: bytes | None = None

    def framed(self) -> bytes:
        """Return every payload as a WebSocket frame, concatenated; computed once."""
        if self._framed is None:
            self._framed = b"".join(ws_frame(p, self.binary) for p in self.payloads)
        return self._framed

    def texts(self) -> list[str]:
        """Return the payloads of a text message as strings (for the generic ASGI path)."""
        return [p.decode("utf-8") for p in self.payloads]


def encode(frame: OutFrame | dict[str, Any], compression: str, fragment_size: int | None) -> Wire:
    """Encode ``frame`` for one variant; unknown compressions fall back to JSON."""
    if compression == "cbor":
        return Wire((_cbor(frame),), binary=True)
    text = to_json(frame)
    if fragment_size is None or len(text) <= fragment_size:
        return Wire((_utf8(text),), binary=False)
    pieces = split(text, fragment_size, f"fragment:{next(_fragment_ids)}")
    return Wire(tuple(_utf8(to_json(p)) for p in pieces), binary=False)


class Outgoing:
    """A frame about to go to many connections, with its encodings cached by variant.

    A ``publish`` frame names its topic as each subscriber spelled it (``pose`` for a robot
    that subscribed by relative name), as rosbridge does, because clients route incoming
    messages by that name; the spelling is therefore part of the variant.
    """

    __slots__ = ("_variants", "frame")

    def __init__(self, frame: OutFrame | dict[str, Any]) -> None:
        self.frame = frame
        self._variants: dict[Variant, Wire] = {}

    def wire(
        self, compression: str = "none", fragment_size: int | None = None, topic: str | None = None
    ) -> Wire:
        """Return the encoding for one variant, encoding it on first use only."""
        return self.wire_of((compression, fragment_size, topic))

    def wire_of(self, variant: Variant) -> Wire:
        """``wire(*variant)``: fan-out keeps each subscriber's variant as one tuple, so
        the look-up per subscriber builds nothing."""
        wire = self._variants.get(variant)
        if wire is None:
            compression, fragment_size, topic = variant
            frame = self.frame
            if topic is not None and frame.get("topic") != topic:
                frame = {**frame, "topic": topic}
            wire = self._variants[variant] = encode(frame, compression, fragment_size)
        return wire
