"""Incoming frames decoded into plain JSON values, within a budget of bytes, nodes and depth.

What a frame may hold is what JSON holds (objects with string keys, arrays, strings,
numbers, booleans, null) plus CBOR's byte strings, which carry ``uint8[]`` as rosbridge's
CBOR does. Nothing else is decoded: no CBOR tag at all (shared references, tags 28 and
29, would let a few hundred bytes stand for a structure of 2**64 leaves that no encoder
ever finishes; big numbers, dates, regular expressions and the rest have no JSON form),
no indefinite lengths, no simple values but false, true and null.

The node budget bounds the memory a frame turns into (one byte of CBOR or three of JSON
can otherwise become a 56-byte Python list) and so the work of anything that walks it
later. A CBOR frame's item headers are checked before cbor2 decodes it; a JSON frame of
fewer bytes than the budget cannot exceed it, and a larger one is counted by its commas,
brackets and braces before ``json.loads`` builds anything. JSON's own parser
bounds its nesting (to the interpreter's recursion limit); ``max_depth`` bounds CBOR's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import cbor2

from telemetry.exceptions import BadFrame

_TRUNCATED = "CBOR frame ends in the middle of an item"
# false, true, null, and half, single and double floats
_PLAIN_SIMPLE = frozenset({20, 21, 22, 25, 26, 27})
_ARGUMENT_BYTES = {24: 1, 25: 2, 26: 4, 27: 8}


@dataclass(frozen=True, slots=True)
class FrameLimits:
    """How large an incoming frame may be: bytes (or characters), nodes and nesting depth."""

    max_bytes: int
    max_nodes: int
    max_depth: int


def decode_frame(data: str | bytes, limits: FrameLimits) -> dict[str, Any]:
    """Return the JSON object in a text frame, or the CBOR map in a binary one.

    Raises BadFrame when the frame breaks a limit, holds anything but plain JSON values
    (and byte strings), cannot be decoded, or is not an object.
    """
    if len(data) > limits.max_bytes:
        raise BadFrame(f"frame of {len(data)} bytes is over the limit of {limits.max_bytes}")
    if isinstance(data, str):
        frame = _json(data, limits)
    else:
        check_plain_cbor(data, limits.max_nodes, limits.max_depth)
        try:
            frame = cbor2.loads(data)
        except cbor2.CBORDecodeError as exc:
            raise BadFrame(f"frame is not valid CBOR: {exc}") from None
    if not isinstance(frame, dict):
        raise BadFrame(f"frame is a {type(frame).__name__}, not an object")
    return frame


def _json(data: str, limits: FrameLimits) -> Any:
    if not json_fits(data, limits.max_nodes):
        raise BadFrame(f"frame has more than {limits.max_nodes} values")
    try:
        return json.loads(data)
    except ValueError as exc:
        raise BadFrame(f"frame is not valid JSON: {exc}") from None
    except RecursionError:
        raise BadFrame("frame is nested too deeply") from None


def json_fits(text: str, max_nodes: int) -> bool:
    """True if the JSON ``text`` can hold no more than ``max_nodes`` values.

    Each value but the first of an array or object follows a comma, and each container
    opens with a bracket or a brace, so counting those bounds the values from above. The
    count includes commas and brackets inside strings, so it errs on the side of refusing;
    it runs at the speed of ``str.count``, and not at all for a text shorter than the budget.
    """
    if len(text) <= max_nodes:
        return True
    return 1 + text.count(",") + text.count("[") + text.count("{") <= max_nodes


def check_plain_cbor(data: bytes, max_nodes: int, max_depth: int) -> None:
    """Raise BadFrame unless ``data`` is exactly one CBOR item of plain JSON types (and byte
    strings) with at most ``max_nodes`` values nested at most ``max_depth`` deep.

    Only the item headers are read; strings are skipped, not decoded. Map keys are not
    counted as values, as in JSON.
    """
    end = len(data)
    pos = nodes = 0
    # Items still to come in each open container: -n for an array of n items, 2n for a map
    # of n pairs (keys and values), so that a map expects a key whenever its count is even.
    remaining: list[int] = []
    while True:
        if pos >= end:
            raise BadFrame(_TRUNCATED)
        initial = data[pos]
        pos += 1
        major, argument = initial >> 5, initial & 31
        if argument >= 24:
            size = _ARGUMENT_BYTES.get(argument)
            if size is None:
                raise BadFrame("CBOR indefinite lengths and reserved values are not accepted")
            argument = int.from_bytes(data[pos : pos + size], "big")
            pos += size
        if remaining:
            left = remaining[-1]
            if left < 0:
                remaining[-1] = left + 1
                nodes += 1
            else:
                remaining[-1] = left - 1
                if left & 1:
                    nodes += 1
                elif major != 3:
                    raise BadFrame("CBOR map keys must be text strings")
        else:
            nodes += 1
        if major < 2:
            pass
        elif major < 4:
            pos += argument
        elif major < 6:
            if argument:
                if argument > end - pos:
                    raise BadFrame(_TRUNCATED)
                remaining.append(-argument if major == 4 else 2 * argument)
                if len(remaining) > max_depth:
                    raise BadFrame(f"frame is nested more than {max_depth} deep")
        elif major == 6:
            raise BadFrame(f"CBOR tag {argument} is not accepted: frames hold plain JSON values")
        elif initial & 31 not in _PLAIN_SIMPLE:
            raise BadFrame(f"CBOR simple value {argument} is not accepted")
        if nodes > max_nodes:
            raise BadFrame(f"frame has more than {max_nodes} values")
        while remaining and not remaining[-1]:
            remaining.pop()
        if not remaining:
            break
    if pos != end:
        raise BadFrame(_TRUNCATED if pos > end else "CBOR frame has bytes after its item")
