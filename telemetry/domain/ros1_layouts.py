"""ROS 1 serialisation of rosbridge JSON by code compiled once per message type.

``compile_encoder`` reads a type's field definitions (``rosbags``' type store) and writes
one Python function for it: nested messages are inlined, so every run of fixed-size fields
between two variable-length ones (a string, a sequence) is packed by one precompiled
``struct.Struct``; numeric arrays are packed in one call. A ``PoseStamped`` is three packs
and a join instead of building a tree of objects and walking it again, which is what the
recorder's CPU budget asks for (it serialises every recorded message).

The rules for values are those of ``ros1.encode``: a missing field is its zero value,
``null`` in a float field is NaN, ``uint8[]`` is base64 text, bytes or a list of numbers,
times are ``sec/nanosec`` or ``secs/nsecs``; a value of the wrong kind raises TypeError,
ValueError, OverflowError, ``struct.error`` or ``binascii.Error``.
"""

from __future__ import annotations

import base64
import struct
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

Encoder = Callable[[Any], bytes]

# Base types as struct codes (ROS 1 is little-endian; byte and char are unsigned, as rosbags
# writes them).
_CODES = {
    "bool": "?",
    "int8": "b",
    "uint8": "B",
    "byte": "B",
    "char": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
_DTYPES = {code: np.dtype("?" if code == "?" else f"<{code}") for code in set(_CODES.values())}
_TIMES = frozenset({"builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"})
_NAN = float("nan")
_EMPTY: Mapping[str, Any] = {}
_U32 = struct.Struct("<I").pack


def compile_encoder(fielddefs: Mapping[str, Any], name: str) -> Encoder:
    """A function from rosbridge JSON of message type ``name`` (a store name such as
    ``geometry_msgs/msg/PoseStamped``) to its ROS 1 bytes. Raises KeyError for an unknown
    type."""
    compiler = _Compiler(fielddefs)
    top = compiler.function(name)
    source = "\n".join(compiler.sources)
    source += f"\ndef encode(x):\n    out = []\n    {top}(x, out)\n    return b''.join(out)\n"
    namespace = compiler.namespace
    exec(compile(source, f"<ros1 encoder of {name}>", "exec"), namespace)
    encoder: Encoder = namespace["encode"]
    return encoder


class _Compiler:
    """The functions (one per message type written in a loop) of one encoder's source."""

    def __init__(self, fielddefs: Mapping[str, Any]) -> None:
        self.fielddefs = fielddefs
        self.namespace: dict[str, Any] = {
            "_Mapping": Mapping,
            "_EMPTY": _EMPTY,
            "_nan": _NAN,
            "_u32": _U32,
            "_numeric": numeric,
            "_strings": strings,
            "_fixed": fixed_length,
        }
        self.functions: dict[str, str] = {}
        self.sources: list[str] = []
        self.variables = 0

    def function(self, name: str) -> str:
        """The name of the function ``f(x, out)`` that appends message ``name`` to ``out``."""
        found = self.functions.get(name)
        if found is not None:
            return found
        found = self.functions[name] = f"_message{len(self.functions)}"
        body = _Body(self)
        if name in _TIMES:
            body.time(name, "x")
        else:
            body.object_check("x", name)
            body.message(name, "x")
        body.flush()
        self.sources.append(f"def {found}(x, out):\n" + "\n".join(body.lines) + "\n")
        return found

    def variable(self) -> str:
        self.variables += 1
        return f"v{self.variables}"

    def packer(self, layout: str) -> str:
        """The name of the precompiled ``struct`` packer of ``layout``."""
        key = f"_pack{len(self.namespace)}"
        self.namespace[key] = struct.Struct("<" + layout).pack
        return key


class _Body:
    """Straight-line code of one function: fixed fields wait in ``codes``/``values`` until
    something of variable length needs them packed (``flush``)."""

    def __init__(self, compiler: _Compiler) -> None:
        self.compiler = compiler
        self.lines: list[str] = []
        self.codes: list[str] = []
        self.values: list[str] = []

    def emit(self, line: str) -> None:
        self.lines.append("    " + line)

    def assign(self, expression: str) -> str:
        name = self.compiler.variable()
        self.emit(f"{name} = {expression}")
        return name

    def fixed(self, code: str, expression: str) -> None:
        self.codes.append(code)
        self.values.append(expression)

    def flush(self) -> None:
        if self.codes:
            pack = self.compiler.packer("".join(self.codes))
            self.emit(f"out.append({pack}({', '.join(self.values)}))")
            self.codes, self.values = [], []

    def object_check(self, value: str, name: str) -> None:
        self.emit(f"if {value} is None: {value} = _EMPTY")
        # a dict (nearly always) skips the slower abstract-class check
        self.emit(
            f"elif type({value}) is not dict and not isinstance({value}, _Mapping): "
            f"raise TypeError('{name} wants an object')"
        )

    def message(self, name: str, value: str) -> None:
        for field, desc in self.compiler.fielddefs[name][1]:
            self.field(desc, f"{value}.get({field!r})")

    def time(self, name: str, raw: str) -> None:
        value = self.assign(raw)
        self.emit(
            f"if type({value}) is not dict and not isinstance({value}, _Mapping): {value} = _EMPTY"
        )
        (_, (_, (sec, _))), (_, (_, (nanosec, _))) = self.compiler.fielddefs[name][1]
        self.fixed(_CODES[sec], f"int({value}.get('sec', {value}.get('secs', 0)) or 0)")
        self.fixed(_CODES[nanosec], f"int({value}.get('nanosec', {value}.get('nsecs', 0)) or 0)")

    def field(self, desc: tuple[Any, Any], raw: str) -> None:
        kind, detail = desc
        if kind == Nodetype.BASE:
            self.base(detail[0], raw)
        elif kind == Nodetype.NAME and detail in _TIMES:
            self.time(detail, raw)
        elif kind == Nodetype.NAME:
            value = self.assign(raw)
            self.object_check(value, detail)
            self.message(detail, value)
        else:
            element, count = detail
            self.array(element, count if kind == Nodetype.ARRAY else 0, raw)

    def base(self, base: str, raw: str) -> None:
        if base == "string":
            value = self.assign(raw)
            self.emit(f"{value} = b'' if {value} is None else str({value}).encode()")
            self.fixed("I", f"len({value})")
            self.flush()
            self.emit(f"out.append({value})")
            return
        code = _CODES[base]
        if code in "fd":
            value = self.assign(raw)
            self.fixed(code, f"_nan if {value} is None else float({value})")
        elif code == "?":
            self.fixed(code, f"bool({raw})")
        else:
            self.fixed(code, f"int({raw} or 0)")

    def array(self, element: tuple[Any, Any], count: int, raw: str) -> None:
        """A fixed-length array (``count`` items, no length written) or a sequence (0)."""
        value = self.assign(raw)
        self.flush()
        kind, detail = element
        if kind == Nodetype.BASE and detail[0] in _CODES:
            self.emit(f"out.append(_numeric({value}, {_CODES[detail[0]]!r}, {count}))")
            return
        if kind == Nodetype.BASE:  # strings
            self.emit(f"out.append(_strings({value}, {count}))")
            return
        if count:
            self.emit(f"{value} = _fixed({value}, {count})")
        else:
            self.emit(f"{value} = {value} or ()")
            self.emit(f"out.append(_u32(len({value})))")
        self.emit(f"for item in {value}: {self.compiler.function(detail)}(item, out)")


def fixed_length(value: Sequence[Any] | None, count: int) -> Sequence[Any]:
    """``value`` as exactly ``count`` items (``count`` zero values when missing)."""
    if not value:
        return [None] * count
    if len(value) != count:
        raise ValueError(f"wants {count} items, got {len(value)}")
    return value


def numeric(value: Any, code: str, count: int) -> bytes:
    """A numeric array of struct ``code``: the length first unless ``count`` fixes it."""
    if code == "B" and isinstance(value, str):
        data = base64.b64decode(value, validate=True)
        items = len(data)
    elif code == "B" and isinstance(value, bytes | bytearray | memoryview):
        data = bytes(value)
        items = len(data)
    else:
        values = [0] * count if count and not value else (value or ())
        data = _pack_numbers(values, code)
        items = len(values)
    if count:
        if items != count:
            raise ValueError(f"wants {count} items, got {items}")
        return data
    return _U32(items) + data


def _pack_numbers(values: Sequence[Any], code: str) -> bytes:
    """One ``struct`` call when every value is a number of the right kind; NaN for ``null``
    in a float array; numpy's conversions (text, floats into ints) otherwise."""
    layout = f"<{len(values)}{code}"
    if code in "fd" and None in values:  # a laser scan's ranges out of reach, often
        values = [_NAN if v is None else v for v in values]
    try:
        return struct.pack(layout, *values)
    except (struct.error, TypeError, OverflowError):
        return np.asarray(values, dtype=_DTYPES[code]).tobytes()


def strings(value: Sequence[Any] | None, count: int) -> bytes:
    """A ``string[]``: each as its length and UTF-8 bytes, the count first unless fixed."""
    items = fixed_length(value, count) if count else (value or ())
    out = [] if count else [_U32(len(items))]
    for item in items:
        data = b"" if item is None else str(item).encode()
        out.append(_U32(len(data)))
        out.append(data)
    return b"".join(out)
