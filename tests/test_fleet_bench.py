"""``bench fleet`` in a tiny configuration (2 robots, 1 simulated minute each run, both on
the test's live server seeded with the demo building): one JSON
object whose keys are the issue's, with the fleet rules at the top and the same keys for
the robots planning alone in ``alone``, and sane values (not the targets: those need 10
robots for 30 minutes)."""

from __future__ import annotations

import io
import json
from contextlib import redirect_stdout
from pathlib import Path

import pytest
from django.core.management import call_command

from benchmarks import fleet

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

KEYS = {
    "waypoints_reached",
    "waypoints_refused_or_moved",
    "deadlocks",
    "collisions",
    "mean_wait_s",
    "throughput_per_hour",
    "cloud_cpu",
}


def test_two_robots_for_a_minute_give_every_figure_with_the_rules_and_alone(
    daphne_server, tmp_path: Path
) -> None:
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "2", "--tokens-file", str(tokens), stdout=io.StringIO())
    options = {
        "url": daphne_server.url,
        "tokens_file": str(tokens),
        "robots": 2,
        "seed": 1,
        "minutes": 1.0,
        "time_scale": 1.0,
        "people": 2,
        "time_limit": 300.0,
        "json": True,
    }
    printed = io.StringIO()
    with redirect_stdout(printed):
        fleet.run(options)
    result = json.loads(printed.getvalue())
    assert set(result) >= KEYS
    assert set(result["alone"]) >= KEYS
    for figures in (result, result["alone"]):
        assert figures["simulated_min"] >= 1.0
        assert all(figures[key] >= 0 for key in KEYS)
        assert 0 < figures["cloud_cpu"] < 2.0  # the server served two robots: some, not all
        assert figures["mean_wait_s"] <= 60 * figures["simulated_min"]
        reached_per_hour = figures["waypoints_reached"] / figures["simulated_min"] * 60
        assert figures["throughput_per_hour"] == pytest.approx(reached_per_hour, rel=0.05)


def test_the_patrols_meet_head_on_and_start_clear_of_each_other() -> None:
    first, second = fleet.patrol(0), fleet.patrol(1)
    assert [w["map"] for w in first][1:3] == ["CorridorB", "CorridorC"]
    assert [w["map"] for w in second][:2] == ["Atrium1", "Office7"]
    starts = [fleet.start(index)[1] for index in range(fleet.MAX_ROBOTS)]
    gaps = [
        ((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5
        for i, a in enumerate(starts)
        for b in starts[i + 1 :]
    ]
    assert min(gaps) >= 1.0
