"""The database out of reach: requests are answered 503 with ``Retry-After``, and the log
says so once per ``REPORT_EVERY`` seconds, not once per request or per loop turn (a fleet
polling every couple of seconds, and the background writers ticking every second, would
write thousands of tracebacks a minute). Everything that meets the outage reports to
``REPORT``; the relay's loops that meet Redis's absence report to ``REDIS_REPORT``."""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable

from django.http import HttpRequest, HttpResponse, JsonResponse
from django.utils.deprecation import MiddlewareMixin

from cloudnav_django.batches import UNREACHABLE

logger = logging.getLogger(__name__)

RETRY_AFTER = 5  # seconds a client is asked to wait
REPORT_EVERY = 10.0


class OutageReport:
    """Logs the first thing an outage cost, then at most one line per ``every`` seconds
    naming what it cost since the last line (requests refused, batches held back, ...)."""

    def __init__(
        self,
        subject: str = "the database",
        every: float = REPORT_EVERY,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.subject = subject
        self.every = every
        self.clock = clock
        self.since: Counter[str] = Counter()
        self.reported_at: float | None = None
        self._lock = threading.Lock()  # views run on worker threads, loops on the event loop

    def failed(self, what: str, error: BaseException) -> None:
        """Count one ``what`` (``"requests refused"``) that the subject's absence cost."""
        with self._lock:
            self.since[what] += 1
            now = self.clock()
            if self.reported_at is not None and now - self.reported_at < self.every:
                return
            costs = ", ".join(f"{count} {name}" for name, count in self.since.items())
            self.since, self.reported_at = Counter(), now
        reason = (str(error).splitlines() or [type(error).__name__])[0]
        logger.warning(
            "%s cannot be reached (%s); since the last report: %s", self.subject, reason, costs
        )


REPORT = OutageReport()
REDIS_REPORT = OutageReport("Redis")


def unavailable() -> JsonResponse:
    """The answer to a request that needed the database while it is out of reach."""
    body = {"detail": "The database cannot be reached; try again shortly."}
    response = JsonResponse(body, status=503, headers={"Retry-After": str(RETRY_AFTER)})
    # Django logs every 5xx at ERROR unless told it was logged: OutageReport speaks for it.
    response._has_been_logged = True  # type: ignore[attr-defined]
    return response


class DatabaseOutageMiddleware(MiddlewareMixin):
    """Answers a view (DRF's included: its handler leaves these errors to Django) that
    could not reach the database with 503 instead of a 500 and a traceback."""

    def process_exception(
        self,
        request: HttpRequest,  # noqa: ARG002 (Django's signature)
        exception: Exception,
    ) -> HttpResponse | None:
        if not isinstance(exception, UNREACHABLE):
            return None
        REPORT.failed("requests refused", exception)
        return unavailable()
