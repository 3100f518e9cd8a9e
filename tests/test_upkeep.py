"""Change detection from robots driving through a changed room: cells that became
occupied or free are proposed after two passes, not after one, saying how many passes and
robots saw each; scans from a robot whose pose is off (far off, or 10 to 15 cm and a few
degrees, which a pose nearby fits better) are not used; the wall a tag hangs on is never
freed; a beam grazing a wall's face frees none of it, and furniture taken from against
a wall is freed."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from maps.domain.slam.scans import Scan
from maps.domain.upkeep import Evidence, UpkeepParams
from robots.agent.sim.laser import Laser, LaserSpec
from robots.agent.sim.world import world_from_grid
from tests.support.upkeep import RES, STORED, TRUTH, room


def drive(
    evidence: Evidence,
    seed: int,
    off: tuple[float, float, float] = (0.0, 0.0, 0.0),
    pose_sigma: float = 0.0,
    robot: str = "",
    truth: np.ndarray = TRUTH,
    others: tuple[tuple[float, float], ...] = (),
) -> None:
    """One pass of ``robot``: a loop 1.2 m inside the walls, a scan every 10 cm, at pose
    estimates ``off`` (x, y, yaw) off (and with Gaussian error of ``pose_sigma`` metres,
    a fiftieth of that in radians)."""
    laser = Laser(world_from_grid(truth, (0.0, 0.0), RES), LaserSpec(), seed=seed)
    angles = laser.spec.angles()
    rng = np.random.default_rng(seed)
    corners = [(1.2, 1.2), (4.8, 1.2), (4.8, 4.8), (1.2, 4.8), (1.2, 1.2)]
    for (ax, ay), (bx, by) in itertools.pairwise(corners):
        heading = math.atan2(by - ay, bx - ax)
        for t in np.linspace(0, 1, 36, endpoint=False):
            pose = (ax + t * (bx - ax), ay + t * (by - ay), heading)
            ranges = laser.scan(pose).astype(np.float64)
            ranges[~np.isfinite(ranges)] = np.nan
            error = rng.normal(0.0, pose_sigma, 3) * (1.0, 1.0, 1 / 50)
            estimate = (
                pose[0] + off[0] + error[0],
                pose[1] + off[1] + error[1],
                pose[2] + off[2] + error[2],
            )
            evidence.add(estimate, Scan(angles, ranges), robot, others)


def cells_between(cells: np.ndarray, rows: range, cols: range) -> int:
    return int(np.count_nonzero(np.isin(cells[:, 0], rows) & np.isin(cells[:, 1], cols)))


@pytest.mark.slow
def test_a_changed_room_is_proposed_after_two_passes_and_not_one() -> None:
    evidence = Evidence(STORED, (0.0, 0.0), RES)
    drive(evidence, seed=1)
    evidence.end_pass()
    assert evidence.proposal().empty
    drive(evidence, seed=2)
    evidence.end_pass()
    proposal = evidence.proposal()
    assert proposal.passes == 2
    # The vanished cabinet: most of its 100 cells seen free on both passes.
    assert cells_between(proposal.removed, range(30, 40), range(30, 40)) >= 80
    assert len(proposal.removed) == cells_between(proposal.removed, range(30, 40), range(30, 40))
    # The new table: its faces (the cells a laser can see) proposed, nothing far from it.
    assert cells_between(proposal.added, range(79, 91), range(69, 91)) >= 40
    assert cells_between(proposal.added, range(79, 91), range(69, 91)) == len(proposal.added)
    assert (proposal.added_passes >= 2).all()
    changed = proposal.applied_to(STORED)
    assert changed[35, 35] == 0
    assert changed[80, 75] == 100


@pytest.mark.slow
def test_the_free_rim_in_front_of_a_new_table_is_not_proposed() -> None:
    """Returns from a face on a cell border fall on both sides of it; the free cells in
    front of the table must not become occupied."""
    evidence = Evidence(STORED, (0.0, 0.0), RES)
    for seed in (1, 2):
        drive(evidence, seed=seed, pose_sigma=0.03)
        evidence.end_pass()
    proposal = evidence.proposal()
    table = cells_between(proposal.added, range(80, 90), range(70, 90))
    assert table >= 40
    assert len(proposal.added) - table <= 2


def test_scans_from_a_robot_whose_pose_is_off_are_not_used() -> None:
    evidence = Evidence(STORED, (0.0, 0.0), RES)
    drive(evidence, seed=1, off=(0.4, 0.4, 0.4 / 3))  # 0.4 m off each way, 7.6 degrees
    assert evidence.scans == 0
    assert evidence.untrusted > 100


@pytest.mark.slow
def test_the_wall_a_tag_hangs_on_is_never_freed_by_the_fleet() -> None:
    """A tag on the cabinet's west face: the cabinet is gone, but its cells stay."""
    tag = (1.5, 1.75, math.pi)  # its face at x = 1.5 m, looking west
    evidence = Evidence(STORED, (0.0, 0.0), RES, tags=[tag])
    for seed in (1, 2):
        drive(evidence, seed=seed)
        evidence.end_pass()
    proposal = evidence.proposal()
    assert cells_between(proposal.removed, range(30, 40), range(30, 40)) == 0
    assert cells_between(proposal.added, range(79, 91), range(69, 91)) >= 40  # still seen


@pytest.mark.slow
def test_a_proposal_says_how_many_passes_and_robots_saw_each_cell() -> None:
    evidence = Evidence(STORED, (0.0, 0.0), RES)
    drive(evidence, seed=1, robot="r1")
    drive(evidence, seed=2, robot="r2")
    assert evidence.proposal().empty  # neither robot ended its pass yet
    evidence.end_pass("r1")
    evidence.end_pass("r2")
    both = evidence.proposal()
    assert (both.passes, both.robots) == (2, 2)
    assert (both.added_robots == 2).all()
    assert (both.removed_robots == 2).all()
    assert len(both.added_robots) == len(both.added)

    alone = Evidence(STORED, (0.0, 0.0), RES)
    for seed in (1, 2):
        drive(alone, seed=seed, robot="r1")
        alone.end_pass("r1")
    proposal = alone.proposal()
    assert (proposal.passes, proposal.robots) == (2, 1)
    assert (proposal.removed_robots == 1).all()
    assert (proposal.removed_passes == 2).all()


def test_a_thick_wall_seen_from_a_heading_a_few_degrees_off_is_not_freed() -> None:
    """A robot reading a tag close up may take a heading several degrees off (the marker's
    two pose solutions): the wall it faces then seems to lie askew, and the returns on
    one side end inside the stored wall. Those beams say nothing of the wall's cells."""
    thick = np.zeros((120, 120), np.int8)
    thick[:, :8] = 100  # a 40 cm wall to the west, the rest open
    laser = Laser(world_from_grid(thick, (0.0, 0.0), RES), LaserSpec(), seed=3)
    angles = laser.spec.angles()
    evidence = Evidence(thick, (0.0, 0.0), RES)
    for robot, skew in (("r0", 0.0), ("r1", 5.0), ("r2", -5.0)):
        for pass_ in range(2):
            for step in range(12):
                pose = (1.2 + 0.1 * pass_, 2.0 + 0.2 * step, math.pi)  # facing the wall
                ranges = laser.scan(pose).astype(np.float64)
                ranges[~np.isfinite(ranges)] = np.nan
                estimate = (pose[0], pose[1], pose[2] + math.radians(skew))
                evidence.add(estimate, Scan(angles, ranges), robot)
            evidence.end_pass(robot)
    assert evidence.scans >= 24  # r0's, at least: a true pose is trusted
    assert len(evidence.proposal().removed) == 0
    assert len(evidence.proposal().added) == 0


@pytest.mark.slow
def test_furniture_taken_from_against_a_wall_is_freed() -> None:
    """A 50 cm deep cabinet stood against the west wall: the returns from the wall behind
    where it stood end 50 cm inside the stored wall, deeper than a pose error puts them,
    so the beams that reached them free the cabinet's cells."""
    stored = room([(50, 70, 2, 12)])  # the cabinet at x 0.1-0.6 m, y 2.5-3.5 m
    evidence = Evidence(stored, (0.0, 0.0), RES)
    for seed in (1, 2):
        drive(evidence, seed=seed, pose_sigma=0.03, truth=room([]))
        evidence.end_pass()
    proposal = evidence.proposal()
    freed = cells_between(proposal.removed, range(50, 70), range(2, 12))
    assert freed >= 150  # of its 200 cells
    assert len(proposal.removed) == freed  # the wall behind it stays
    assert len(proposal.added) == 0


@pytest.mark.slow
def test_scans_from_a_pose_10_to_15_cm_off_are_dropped_and_propose_nothing() -> None:
    """Off by this much (or 3 degrees), most returns still end within a cell of a wall
    (the trust check passes), but a pose nearby fits them to the stored walls better:
    the scans are not used, and an unchanged room gets no proposal from them."""
    for off in ((0.1, 0.0, 0.0), (0.0, -0.12, 0.0), (0.0, 0.0, math.radians(3))):
        evidence = Evidence(STORED, (0.0, 0.0), RES)
        for seed in (1, 2):
            drive(evidence, seed=seed, off=off, truth=STORED)
            evidence.end_pass()
        assert evidence.scans <= 10, off
        assert evidence.proposal().empty, off


def test_scans_from_a_pose_a_few_cm_off_are_used() -> None:
    evidence = Evidence(STORED, (0.0, 0.0), RES)
    drive(evidence, seed=1, pose_sigma=0.02, truth=STORED)
    assert evidence.misaligned <= 0.1 * evidence.scans
    assert evidence.untrusted == 0


def test_beams_grazing_a_wall_face_do_not_free_it() -> None:
    """A 10 cm partition across the room's south half, seen along its faces from the
    loop: beams from a pose a few centimetres and a degree off run inside its face cells
    for metres before they end on the far wall. They free none of it."""
    partition = room([(58, 60, 2, 60)])  # y 2.9-3.0 m, x 0.1-3.0 m
    evidence = Evidence(partition, (0.0, 0.0), RES)
    rng = np.random.default_rng(7)
    laser = Laser(world_from_grid(partition, (0.0, 0.0), RES), LaserSpec(), seed=7)
    for robot in ("r1", "r2", "r3"):
        for step in range(30):
            pose = (3.3 + 0.08 * step, 2.95 + rng.normal(0.0, 0.05), math.pi)  # facing west
            ranges = laser.scan(pose).astype(np.float64)
            ranges[~np.isfinite(ranges)] = np.nan
            error = rng.normal(0.0, 0.02, 3) * (1.0, 1.0, 1.0)  # 2 cm and about a degree
            estimate = (pose[0] + error[0], pose[1] + error[1], pose[2] + error[2])
            evidence.add(estimate, Scan(laser.spec.angles(), ranges), robot)
        evidence.end_pass(robot)
    assert evidence.scans >= 60
    assert cells_between(evidence.proposal().removed, range(58, 60), range(2, 60)) == 0


@pytest.mark.slow
def test_a_surface_just_beyond_the_grid_s_rim_is_not_proposed() -> None:
    """A sub-map cut from a building may end at the face of a wall it leaves out; the
    returns from that face, with centimetres of error, land in the rim's free cells."""
    cut = STORED[:, 2:]  # the room without its west wall: its face is the grid's edge
    evidence = Evidence(cut, (2 * RES, 0.0), RES)
    for seed in (1, 2):
        drive(evidence, seed=seed, pose_sigma=0.02)
        evidence.end_pass()
    proposal = evidence.proposal()
    assert evidence.scans >= 200
    assert cells_between(proposal.added, range(0, 120), range(0, 1)) == 0
    assert cells_between(proposal.added, range(79, 91), range(67, 89)) >= 40  # the table


@pytest.mark.slow
def test_another_robot_standing_in_the_room_is_not_proposed_as_an_obstacle() -> None:
    """A robot waiting in the room (a 0.35 m body at (2.5, 3) m) is seen on every pass;
    where the other robots said they were, returns are their bodies, not the map."""
    waiting = np.array(STORED, copy=True)
    waiting[57:64, 47:54] = 100
    body = (range(55, 66), range(45, 56))
    told, untold = Evidence(STORED, (0.0, 0.0), RES), Evidence(STORED, (0.0, 0.0), RES)
    for seed in (1, 2):
        drive(told, seed=seed, truth=waiting, robot=f"r{seed}", others=((2.52, 2.97),))
        drive(untold, seed=seed, truth=waiting, robot=f"r{seed}")
        told.end_pass()
        untold.end_pass()
    assert cells_between(untold.proposal().added, *body) >= 10  # what it was before
    assert cells_between(told.proposal().added, *body) == 0
    assert told.proposal().empty


@pytest.mark.slow
def test_a_cell_diagonal_to_a_wall_s_corner_is_not_proposed() -> None:
    """A pose 3 cm and 0.6 degrees off puts some of the cabinet's corner returns in the
    free cell diagonal to it, pass after pass; it is the same cabinet."""
    for off in ((0.03, 0.03, 0.01), (-0.03, 0.03, -0.01)):
        evidence = Evidence(STORED, (0.0, 0.0), RES)
        for seed in (1, 2, 3):
            drive(evidence, seed=seed, off=off, truth=STORED, robot=f"r{seed}")
            evidence.end_pass()
        assert evidence.scans >= 300
        assert cells_between(evidence.proposal().added, range(28, 42), range(28, 42)) == 0


@pytest.mark.slow
def test_scans_half_a_metre_off_along_a_corridor_free_no_door_frame() -> None:
    """Off by 0.5 m along a corridor, the long walls fit every pose of the narrow
    alignment window alike, so the scans pass that check, and the beams through a side
    door run through its frame. The best pose of the wide window (the truth) frees
    nothing, so those scans are dropped: no wall is proposed removed. With the wide window
    as narrow as the first (``free_window_xy`` 0.2 m), the frame is proposed removed."""
    corridor = np.zeros((80, 400), np.int8)  # 20 x 4 m: a 2 m corridor, a room north of it
    corridor[:2, :] = corridor[-2:, :] = corridor[:, :2] = corridor[:, -2:] = 100
    corridor[38:40, :] = 100  # the corridor's north wall...
    corridor[38:40, 200:218] = 0  # ...with a 0.9 m door at x 10 to 10.9 m
    corridor[40:, 240:242] = 100  # the room's east wall

    def passes(params: UpkeepParams | None) -> Evidence:
        evidence = Evidence(corridor, (0.0, 0.0), RES, params=params)
        rng = np.random.default_rng(3)
        laser = Laser(world_from_grid(corridor, (0.0, 0.0), RES), LaserSpec(), seed=3)
        for robot, heading in (("r1", 0.0), ("r2", math.pi), ("r3", 0.0)):
            for step in range(60):
                pose = (7.0 + 0.1 * step, 1.0 + rng.normal(0.0, 0.02), heading)
                ranges = laser.scan(pose).astype(np.float64)
                ranges[~np.isfinite(ranges)] = np.nan
                estimate = (pose[0] + 0.5, pose[1], pose[2])
                evidence.add(estimate, Scan(laser.spec.angles(), ranges), robot)
            evidence.end_pass(robot)
        return evidence

    evidence = passes(None)
    assert evidence.scans >= 20  # the scans that free nothing are still used
    assert len(evidence.proposal().removed) == 0
    narrow = UpkeepParams(free_window_xy=0.2, free_window_yaw=math.radians(4), free_step=0.04)
    assert len(passes(narrow).proposal().removed) >= 10
