"""``manage.py bench agent`` runs and reports CPU per robot (a short smoke run against a
live server seeded with the demo building)."""

from __future__ import annotations

import io
from contextlib import redirect_stdout
from pathlib import Path

import pytest
from django.core.management import call_command

from benchmarks import agent

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]


def test_it_reports_cpu_per_robot(daphne_server, tmp_path: Path):
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "1", "--tokens-file", str(tokens), stdout=io.StringIO())
    options = {
        "robots": 1,
        "duration": 2.0,
        "warmup": 1.0,
        "time_scale": 2.0,
        "camera_rate": 1.0,
        "particles": 100,
        "planner": "dwa",
        "people": 0,
        "people_seed": 0,
        "url": daphne_server.url,
        "tokens_file": str(tokens),
    }
    printed = io.StringIO()
    with redirect_stdout(printed):
        agent.run(options)
    assert "1 robot(s)" in printed.getvalue()
    assert "% of a core per robot" in printed.getvalue()
