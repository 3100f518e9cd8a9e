"""The rosbridge benchmark runs end to end (a tiny load; the figures themselves are not tested)."""

from __future__ import annotations

import pytest
from django.core.management import call_command


@pytest.mark.slow
def test_bench_rosbridge_prints_a_measurement(capsys):
    call_command(
        "bench",
        "rosbridge",
        "--robots",
        "3",
        "--subscribers",
        "2",
        "--rate",
        "20",
        "--duration",
        "1",
        "--warmup",
        "0.5",
    )
    header, row = capsys.readouterr().out.strip().splitlines()[-2:]
    assert "delivered/s" in header
    robots, _rate, subscribers, _offered, delivered, loss = row.split()[:6]
    assert (robots, subscribers) == ("3", "2")
    assert float(delivered) > 0
    assert loss == "0.00%"
