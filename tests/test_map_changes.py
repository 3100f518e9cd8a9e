"""Upkeep through the server: robots driving normally through a changed room give laser
evidence to their process's runner; after two passes the sub-map has a proposed change;
an admin accepts it (or the cells kept) as a new version, or rejects it; a change made
on a version no longer current is refused and stays open."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from django.contrib.auth.models import User

from cloudnav_core.messages import pose_stamped
from maps import services, versions
from maps.domain.mapfile import MapMetadata, export_map, load_map_upload, map_yaml_text
from maps.mapping.upkeep import UpkeepRunner
from maps.models import Building, ChangeProposal, SubMap
from robots.agent.sim.laser import Laser, LaserSpec
from robots.agent.sim.world import world_from_grid
from tests.conftest import FakeHub, client_for
from tests.support.upkeep import RES, STORED, TRUTH

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
            runner.process(runner.queue.take_all())
    hub.send("/r1/pose", dict(pose_stamped("boccioni_1/CorridorA", (0.0, 0.0, 0.0), 1.0)))
    hub.send("/r1/scan", laser.message(laser.scan((1.0, 1.0, 0.0)), 1.0))
    runner.process(runner.queue.take_all())


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


@pytest.mark.slow
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
    assert shown["robots"] == 1  # both passes were r1's
    assert shown["added_robots"] == [1] * len(shown["added"])
    assert shown["removed_robots"] == [1] * len(shown["removed"])


@pytest.mark.slow
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


@pytest.mark.slow
def test_a_change_on_a_version_no_longer_current_is_refused_and_stays_open(
    proposal: ChangeProposal, admin: User, lab: SubMap
) -> None:
    versions.rollback(lab, 1)  # the sub-map moves on to version 2
    answer = client_for(admin).post(f"{CHANGES}{proposal.pk}/accept")
    assert answer.status_code == 409
    assert answer.json()["current"] == 2
    assert ChangeProposal.objects.get().state == "open"
    assert lab.versions.count() == 2


@pytest.mark.slow
def test_only_admins_decide_and_outsiders_see_nothing(
    proposal: ChangeProposal, operator: User, outsider: User, admin: User
) -> None:
    assert client_for(operator).post(f"{CHANGES}{proposal.pk}/accept").status_code == 403
    assert client_for(outsider).get(CHANGES).status_code == 404
    assert client_for(outsider).post(f"{CHANGES}{proposal.pk}/reject").status_code == 404
    assert client_for(admin).post(f"{CHANGES}{proposal.pk}/reject").json()["state"] == "rejected"
    assert client_for(admin).post(f"{CHANGES}{proposal.pk}/reject").status_code == 409


@pytest.mark.slow
def test_it_rejects_outsider(proposal: ChangeProposal, outsider: User) -> None:
    assert client_for(outsider).get(CHANGES).status_code == 404


def drive_unchanged(
    runner: UpkeepRunner,
    hub: FakeHub,
    seed: int,
    start: float,
    pose_first: bool = True,
    through: Callable[[int, str], bool] | None = None,
    truth: np.ndarray = STORED,
) -> float:
    """r1 drives a loop in the unchanged lab at 1 m/s scanning at 5 Hz (20 cm between
    scans), stamping each scan and the pose it gives for it alike, from ``start`` (its own
    clock); ``pose_first`` as the simulated robot sends them, else the scan first (a ROS
    robot's AMCL publishes the pose of a scan after it). ``through(i, topic)``: whether the
    i-th message on ``topic`` gets through (a congested robot drops telemetry). Returns
    the clock at the end."""
    laser = Laser(world_from_grid(truth, (0.0, 0.0), RES), LaserSpec(), seed=seed)
    corners = [(1.2, 1.2), (4.8, 1.2), (4.8, 4.8), (1.2, 4.8), (1.2, 1.2)]
    stamp = start
    index = 0
    for (ax, ay), (bx, by) in itertools.pairwise(corners):
        heading = math.atan2(by - ay, bx - ax)
        for t in np.linspace(0, 1, 18, endpoint=False):
            pose = (ax + t * (bx - ax), ay + t * (by - ay), heading)
            stamp += 0.2
            index += 1
            messages = [
                ("/r1/pose", pose_message(pose, stamp)),
                ("/r1/scan", laser.message(laser.scan(pose), stamp)),
            ]
            for topic, message in messages if pose_first else messages[::-1]:
                if through is None or through(index, topic):
                    hub.send(topic, message)
    runner.process(runner.queue.take_all())
    return stamp


def pose_message(pose: tuple[float, float, float], stamp: float) -> dict[str, Any]:
    return dict(pose_stamped("boccioni_1/Lab", pose, stamp))


def test_a_scan_is_placed_at_the_pose_of_its_own_stamp_even_when_that_pose_comes_after_it(
    lab: SubMap,
) -> None:
    hub = FakeHub("r1")
    runner = UpkeepRunner(hub)
    runner.sync_taps()
    clock = 1000.0
    for seed in (1, 2):
        clock = drive_unchanged(runner, hub, seed, clock, pose_first=False)
        runner.maps["boccioni_1/Lab"].evidence.end_pass()
    runner.save()
    held = runner.maps["boccioni_1/Lab"].evidence
    assert held.scans >= 90
    assert not ChangeProposal.objects.exists()  # nothing changed: nothing proposed
    assert runner.unpaired == 0


def lost_on_a_congested_link(index: int, topic: str) -> bool:
    """The i-th pose gets through unless i % 3 == 2, the i-th scan unless i % 3 == 1:
    the scans of those ticks come with no pose of theirs, after a pose of a tick before."""
    return index % 3 != (2 if topic == "/r1/pose" else 1)


def test_a_scan_whose_pose_never_came_is_not_used_at_another_pose(lab: SubMap) -> None:
    hub = FakeHub("r1")
    runner = UpkeepRunner(hub)
    runner.sync_taps()
    clock = 1000.0
    for seed in (1, 2):  # of three poses and scans, a congested link loses one of each
        clock = drive_unchanged(runner, hub, seed, clock, through=lost_on_a_congested_link)
        runner.maps["boccioni_1/Lab"].evidence.end_pass()
    runner.save()
    assert not ChangeProposal.objects.exists()  # nothing changed: nothing proposed
    assert runner.unpaired >= 40  # the scans whose pose was lost
    assert runner.maps["boccioni_1/Lab"].evidence.scans >= 40


@pytest.mark.slow
def test_a_robots_pass_ends_when_it_leaves_and_after_a_minute_of_its_own_clock(
    lab: SubMap,
) -> None:
    hub = FakeHub("r1")
    runner = UpkeepRunner(hub)
    runner.sync_taps()
    clock = drive_unchanged(runner, hub, 1, 1000.0)  # 14.4 s of the robot's clock
    held = runner.maps["boccioni_1/Lab"]
    assert held.evidence.passes == 0
    elsewhere = dict(pose_stamped("boccioni_1/CorridorA", (0.0, 0.0, 0.0), clock + 0.1))
    hub.send("/r1/pose", elsewhere)
    hub.send("/r1/scan", runner_scan(clock + 0.1))
    runner.process(runner.queue.take_all())
    assert held.evidence.passes == 1  # it left the lab
    clock = drive_unchanged(runner, hub, 2, clock + 100.0)  # back, much later
    assert held.evidence.passes == 1  # a new pass, not ended by the old one's start
    for seed in range(3, 7):
        clock = drive_unchanged(runner, hub, seed, clock)
    assert held.evidence.passes == 2  # 72 s of its own clock in the lab


def runner_scan(stamp: float) -> dict[str, Any]:
    laser = Laser(world_from_grid(STORED, (0.0, 0.0), RES), LaserSpec(), seed=0)
    return dict(laser.message(laser.scan((1.0, 1.0, 0.0)), stamp))


def test_another_robot_waiting_in_the_sub_map_is_not_proposed(lab: SubMap) -> None:
    """r2 stands at (2.5, 3) m in the lab (it said so); r1 sees its body on every pass."""
    waiting = np.array(STORED, copy=True)
    waiting[57:64, 47:54] = 100
    hub = FakeHub("r1", "r2")
    runner = UpkeepRunner(hub)
    runner.sync_taps()
    hub.send("/r2/pose", dict(pose_stamped("boccioni_1/Lab", (2.52, 2.97, 0.0), 1000.0)))
    clock = 1000.0
    for seed in (1, 2, 3):
        clock = drive_unchanged(runner, hub, seed, clock, truth=waiting)
        runner.maps["boccioni_1/Lab"].evidence.end_pass("r1")
    runner.save()
    assert runner.maps["boccioni_1/Lab"].evidence.scans >= 90
    assert not ChangeProposal.objects.exists()
