"""Robot tokens never reach a log.

A robot may put its token in the URL (``?token=``: a browser's WebSocket or ``<img>`` can
only do that), and daphne's access log writes every HTTP request's path with its query
to stdout, outside Python's logging. ``install`` makes that log redact it; ``RedactingFilter``
(on the console handler in ``settings.LOGGING``) does the same for every logged record,
its traceback included, so an error that quotes a URL or a token hides it too.
"""

from __future__ import annotations

import logging
import re
from typing import Any

from robots.tokens import TOKEN_PREFIX

REDACTED = "[redacted]"
# A ``token`` query parameter's value, and anything shaped like a robot token.
_SECRETS = re.compile(
    rf"(?i)(?<![A-Za-z0-9_])(token=)[^&\s\"'#]+|{re.escape(TOKEN_PREFIX)}[A-Za-z0-9_\-]+"
)


def redact(text: str) -> str:
    """Return ``text`` with token query values and robot tokens replaced by ``[redacted]``."""
    return _SECRETS.sub(_replacement, text)


def _replacement(match: re.Match[str]) -> str:
    return (match.group(1) or TOKEN_PREFIX) + REDACTED


class RedactingFilter(logging.Filter):
    """Redacts a record's message and traceback before any handler formats it."""

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        record.msg, record.args = redact(message), None
        if record.exc_info and not record.exc_text:
            record.exc_text = logging.Formatter().formatException(record.exc_info)
        if record.exc_text:
            record.exc_text = redact(record.exc_text)
        return True


def install() -> None:
    """Make daphne's access log redact what it writes (no-op without daphne)."""
    try:
        from daphne import access
    except ImportError:
        return
    generator = access.AccessLogGenerator
    if getattr(generator.write_entry, "redacts", False):
        return
    write_entry = generator.write_entry

    def redacting_write_entry(self: Any, host: Any, date: Any, request: str, **kw: Any) -> None:
        write_entry(self, host, date, redact(request), **kw)

    redacting_write_entry.redacts = True  # type: ignore[attr-defined]
    generator.write_entry = redacting_write_entry
