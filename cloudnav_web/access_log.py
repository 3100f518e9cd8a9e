"""daphne's access log through Python's logging, with unchanged checks kept out of INFO.

daphne writes one line per request to stdout (``AccessLogGenerator``), outside logging, so
a robot's conditional bundle check every 2 s and a page's polls filled the demo's output.
``install`` sends those lines (same text) to the ``cloudnav_web.access`` logger instead:
``LOG_LEVEL`` and the handlers of ``settings.LOGGING`` (redaction included) apply, and an
answer that says nothing changed (``304 Not Modified``) is logged at DEBUG. An access log
daphne was told to write to a file (``--access-log PATH``) is left as it is.
"""

from __future__ import annotations

import logging
import sys
from typing import Any

logger = logging.getLogger("cloudnav_web.access")

NOT_MODIFIED = 304


def level_of(status: Any) -> int:
    """The level of an access-log entry: DEBUG for an unchanged check, else INFO."""
    return logging.DEBUG if status == NOT_MODIFIED else logging.INFO


def install() -> None:
    """Route daphne's stdout access log to ``cloudnav_web.access`` (no-op without daphne)."""
    try:
        from daphne import access
    except ImportError:
        return
    generator = access.AccessLogGenerator
    if getattr(generator.write_entry, "logs", False):
        return
    write_entry = generator.write_entry

    def logging_write_entry(
        self: Any, host: Any, date: Any, request: str, status: Any = None, length: Any = None,
        ident: Any = None, user: Any = None,
    ) -> None:  # fmt: skip
        if self.stream is not sys.stdout:
            write_entry(self, host, date, request, status, length, ident, user)
            return
        level = level_of(status)
        if logger.isEnabledFor(level):
            text = '%s %s %s "%s" %s %s'
            values = (host, ident or "-", user or "-", request, status or "-", length or "-")
            logger.log(level, text, *values)

    logging_write_entry.logs = True  # type: ignore[attr-defined]
    generator.write_entry = logging_write_entry
