"""Text any of the project's databases stores as it is: PostgreSQL refuses NUL in text and
JSON, and no database takes a string that is not valid Unicode (a lone surrogate, which
JSON's ``"\\ud800"`` decodes to). What robots and people send is cleaned where it arrives
(events, mission outcomes), so one odd string never reaches, and never blocks, a batch.
"""

from __future__ import annotations

from typing import Any

REPLACEMENT = "\ufffd"


def storable_text(text: str) -> str:
    """``text`` with each NUL and lone surrogate replaced by U+FFFD."""
    if "\x00" in text:
        text = text.replace("\x00", REPLACEMENT)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        text = text.encode("utf-16", "surrogatepass").decode("utf-16", "replace")
    return text


def storable(value: Any) -> Any:
    """``value`` (a JSON-like structure) with every string in it, keys too, made storable
    (``storable_text``); other values as they are."""
    if isinstance(value, str):
        return storable_text(value)
    if isinstance(value, dict):
        return {storable(k): storable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [storable(v) for v in value]
    return value
