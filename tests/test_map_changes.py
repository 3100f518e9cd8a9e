"""Upkeep through the server: robots driving normally through a changed room give laser
evidence to their process's runner; after two passes the sub-map has a proposed change;
an admin accepts it (or the cells kept) as a new version, or rejects it; a change made
on a version no longer current is refused and stays open."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from django.contrib.auth.models import User

from maps import services, versions
from maps.domain.mapfile import MapMetadata, export_map, load_map_upload, map_yaml_text
from maps.mapping.upkeep import UpkeepRunner
from maps.models import Building, ChangeProposal, SubMap
from robots.agent.sim.laser import Laser, LaserSpec
from robots.agent.sim.world import world_from_grid
from telemetry.domain.messages import pose_stamped
from tests.conftest import FakeHub, client_for
from tests.test_upkeep import RES, STORED, TRUTH

CHANGES = "/api/buildings/boccioni_1/maps/Lab/changes/"


@pytest.fixture
def lab(building: Building) -> SubMap:
    meta = MapMetadata("Lab.pgm", RES, (0.0, 0.0, 0.0), 0.65, 0.196, False)
    pgm, meta = export_map(STORED, meta, "Lab.pgm")
    loaded = load_map_upload(map_yaml_text(meta).encode(), {"Lab.pgm": pgm}, 10**7)
    return services.save_submap(building, "Lab", loaded)[0]


def drive_through(runner: UpkeepRunner, hub: FakeHub, seed: int) -> None:
    """robot r1 drives a loop in the lab, then into the corridor (ending its pass)."""
    laser = Laser(world_from_grid(TRUTH, (0.0, 0.0), RES), LaserSpec(), seed=seed)
    corners = [(1.2, 1.2), (4.8, 1.2), (4.8, 4.8), (1.2, 4.8), (1.2, 1.2)]
    for (ax, ay), (bx, by) in itertools.pairwise(corners):
        heading = math.atan2(by - ay, bx - ax)
        for t in np.linspace(0, 1, 36, endpoint=False):
            pose = (ax + t * (bx - ax), ay + t * (by - ay), heading)
            hub.send("/r1/pose", dict(pose_stamped("boccioni_1/Lab", pose, 1.0)))
            hub.send("/r1/scan", laser.message(laser.scan(pose), 1.0))
            runner.process(list(runner.queue))
            runner.queue.clear()
    hub.send("/r1/pose", dict(pose_stamped("boccioni_1/CorridorA", (0.0, 0.0, 0.0), 1.0)))
    hub.send("/r1/scan", laser.message(laser.scan((1.0, 1.0, 0.0)), 1.0))
    runner.process(list(runner.queue))
    runner.queue.clear()


@pytest.fixture
def proposal(lab: SubMap) -> ChangeProposal:
    hub = FakeHub("r1")
    runner = UpkeepRunner(hub)
    runner.sync_taps()
    assert set(hub.taps) == {"/r1/pose", "/r1/scan"}
    drive_through(runner, hub, seed=1)
    runner.save()
    assert not ChangeProposal.objects.exists()  # one pass is not enough
    drive_through(runner, hub, seed=2)
    runner.save()
    hub.here.clear()
    runner.sync_taps()
    assert hub.taps == {}
    return ChangeProposal.objects.get()


def test_two_passes_through_a_changed_room_propose_the_change(
    proposal: ChangeProposal, viewer: User
) -> None:
    [shown] = client_for(viewer).get(f"{CHANGES}?state=open").json()
    assert shown["based_on"] == 1
    assert shown["passes"] == 2
    removed = {tuple(c) for c in shown["removed"]}
    assert len(removed & {(r, c) for r in range(30, 40) for c in range(30, 40)}) >= 80
    assert len(shown["added"]) >= 40
    assert len(shown["added_passes"]) == len(shown["added"])


def test_an_admin_accepts_the_cells_kept_as_a_new_version(
    proposal: ChangeProposal, admin: User, lab: SubMap
) -> None:
    kept = proposal.removed[:10]
    answer = client_for(admin).post(
        f"{CHANGES}{proposal.pk}/accept", {"added": [], "removed": kept}, format="json"
    )
    assert answer.status_code == 200
    assert answer.json()["state"] == "accepted"
    assert answer.json()["version"] == 2
    version = versions.version_of(lab, 2)
    assert version.reason == "change"
    grid = services.grid_of(version)
    assert all(grid[r, c] == 0 for r, c in kept)
    assert int(np.count_nonzero(grid != services.grid_of(versions.version_of(lab, 1)))) == 10


def test_a_change_on_a_version_no_longer_current_is_refused_and_stays_open(
    proposal: ChangeProposal, admin: User, lab: SubMap
) -> None:
    versions.rollback(lab, 1)  # the sub-map moves on to version 2
    answer = client_for(admin).post(f"{CHANGES}{proposal.pk}/accept")
    assert answer.status_code == 409
    assert answer.json()["current"] == 2
    assert ChangeProposal.objects.get().state == "open"
    assert lab.versions.count() == 2


def test_only_admins_decide_and_outsiders_see_nothing(
    proposal: ChangeProposal, operator: User, outsider: User, admin: User
) -> None:
    assert client_for(operator).post(f"{CHANGES}{proposal.pk}/accept").status_code == 403
    assert client_for(outsider).get(CHANGES).status_code == 404
    assert client_for(outsider).post(f"{CHANGES}{proposal.pk}/reject").status_code == 404
    assert client_for(admin).post(f"{CHANGES}{proposal.pk}/reject").json()["state"] == "rejected"
    assert client_for(admin).post(f"{CHANGES}{proposal.pk}/reject").status_code == 409


def test_it_rejects_outsider(proposal: ChangeProposal, outsider: User) -> None:
    assert client_for(outsider).get(CHANGES).status_code == 404
