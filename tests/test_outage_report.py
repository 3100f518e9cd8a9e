"""The database's absence is logged once per interval, naming what it cost meanwhile."""

from __future__ import annotations

import logging

from django.db import OperationalError

from cloudnav_django.outage import OutageReport


def test_it_logs_the_first_failure_then_one_line_per_interval_with_what_it_cost(caplog):
    now = [0.0]
    report = OutageReport(every=10.0, clock=lambda: now[0])
    down = OperationalError("connection refused\n\tIs the server running?")
    with caplog.at_level(logging.WARNING, logger="cloudnav_django.outage"):
        report.failed("requests refused", down)
        for second in range(1, 10):
            now[0] = float(second)
            report.failed("requests refused", down)
            report.failed("event batches held back", down)
        now[0] = 10.0
        report.failed("requests refused", down)
    assert [r.getMessage() for r in caplog.records] == [
        "the database cannot be reached (connection refused); since the last report: "
        "1 requests refused",
        "the database cannot be reached (connection refused); since the last report: "
        "10 requests refused, 9 event batches held back",
    ]
