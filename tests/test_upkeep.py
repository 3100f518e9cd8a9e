"""Change detection from robots driving through a changed room: cells that became
occupied or free are proposed after two passes, not after one, saying how many passes and
robots saw each; scans from a robot whose pose is off are not used; the wall a tag hangs
on is never freed; a return may end inside a stored wall by as much as a pose error at
its range could put it (the wall is not freed for it), and deeper only when what stood
in front of the wall is gone (furniture taken from against a wall is freed)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from maps.domain.slam import Scan
from maps.domain.upkeep import Evidence, UpkeepParams, wall_tolerance
from robots.agent.sim.laser import Laser, LaserSpec
from robots.agent.sim.world import world_from_grid

RES = 0.05


def room(boxes: list[tuple[int, int, int, int]]) -> np.ndarray:
    """A 6 x 6 m room (120 cells a side) walled round, with boxes (row0, row1, col0, col1)."""
    grid = np.zeros((120, 120), np.int8)
    grid[:2, :] = grid[-2:, :] = grid[:, :2] = grid[:, -2:] = 100
    for r0, r1, c0, c1 in boxes:
        grid[r0:r1, c0:c1] = 100
    return grid


STORED = room([(30, 40, 30, 40)])  # a cabinet at (1.5-2, 1.5-2) m
TRUTH = room([(80, 90, 70, 90)])  # ...gone; a table at (3.5-4.5, 4-4.5) m instead


def drive(
    evidence: Evidence,
    seed: int,
    offset: float = 0.0,
    pose_sigma: float = 0.0,
    robot: str = "",
    truth: np.ndarray = TRUTH,
) -> None:
    """One pass of ``robot``: a loop 1.2 m inside the walls, a scan every 10 cm, at pose
    estimates ``offset`` off (and with Gaussian error of ``pose_sigma`` metres, a
    fiftieth of that in radians)."""
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
                pose[0] + offset + error[0],
                pose[1] + offset + error[1],
                pose[2] + offset / 3 + error[2],
            )
            evidence.add(estimate, Scan(angles, ranges), robot)


def cells_between(cells: np.ndarray, rows: range, cols: range) -> int:
    return int(np.count_nonzero(np.isin(cells[:, 0], rows) & np.isin(cells[:, 1], cols)))


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
    drive(evidence, seed=1, offset=0.4)  # 0.4 m off each way and 7.6 degrees
    assert evidence.scans == 0
    assert evidence.untrusted > 100


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


def test_a_return_may_end_inside_a_wall_by_a_tolerance_that_grows_with_its_range() -> None:
    """A pose 10 cm off toward a thick wall puts the returns 10 cm inside it: within the
    tolerance at their range, so their beams do not free the wall (every scan is used
    here, ``trust`` 0, to see the beams' rule alone: by default such a scan is not)."""
    params = UpkeepParams()
    allowed = wall_tolerance(np.array([0.0, 1.0, 4.0]), params)
    assert allowed[0] == params.wall_tolerance
    assert allowed[0] < allowed[1] < allowed[2]
    assert math.isclose(allowed[2] - allowed[1], 3 * params.wall_tolerance_per_m)

    thick = np.zeros((120, 120), np.int8)
    thick[:, :8] = 100  # a 40 cm wall to the west, the rest open
    laser = Laser(world_from_grid(thick, (0.0, 0.0), RES), LaserSpec(), seed=4)
    angles = laser.spec.angles()
    evidence = Evidence(thick, (0.0, 0.0), RES, UpkeepParams(trust=0.0))
    added = 0
    for robot in ("r1", "r2"):
        for step in range(12):
            pose = (1.2, 2.0 + 0.2 * step, math.pi)  # facing the wall, 0.8 m from it
            ranges = laser.scan(pose).astype(np.float64)
            ranges[~np.isfinite(ranges)] = np.nan
            added += 1
            evidence.add((pose[0] - 0.1, pose[1], pose[2]), Scan(angles, ranges), robot)
        evidence.end_pass(robot)
    assert evidence.untrusted == 0
    assert evidence.scans == added
    assert len(evidence.proposal().removed) == 0


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
