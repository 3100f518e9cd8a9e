"""Visual mapping sessions: the 2D grid derived from a known room's depth, bad frames
refused with nothing kept, and a session fed rendered camera frames through the runner
whose published map carries its keyframes as the sub-map's relocalisation map, which
places a robot waking up there."""

from __future__ import annotations

import base64
import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from asgiref.sync import sync_to_async
from django.contrib.auth.models import User

from benchmarks.visual_tracking import START, corridor_tour, rendered
from cloudnav_core import messages
from cloudnav_core.camera import CameraModel, Intrinsics
from cloudnav_core.se2 import Pose, compose
from maps.domain.demo_building import demo_building
from maps.domain.keyframes import thinned
from maps.domain.visual_grid import grid_of_views, obstacle_scan
from maps.domain.visual_mapping import (
    GRID_TOLERANCE,
    Frame,
    VisualMapper,
    frame_of,
    stored_keyframes,
)
from maps.domain.visual_slam import _moved
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError
from maps.mapping import runner as mapping_runner
from maps.mapping.runner import MappingRunner
from maps.models import Building, Keyframe, MappingSession, SubMap
from robots.agent.perception import pinhole_calibration
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world, world_from_grid
from robots.models import Robot
from tests.conftest import FakeHub, client_for, make_robot
from tests.support.mapping_sessions import _drained, _session, _until, online
from tests.support.visual_room import RESOLUTION, frames, image_message, known_room

SESSIONS = "/api/mapping/sessions/"


def test_the_grid_from_a_known_rooms_depth_has_its_walls_and_its_free_floor() -> None:
    camera = Camera(world_from_grid(known_room(), (0.0, 0.0), RESOLUTION), seed=1)
    views = []
    for at_x, at_y in [(1.5, 2.0), (3.0, 2.0), (4.5, 2.0), (3.0, 1.2), (3.0, 2.8)]:
        for k in range(12):
            pose = (at_x, at_y, k * math.pi / 6)
            _, depth = camera.capture(pose)
            assert depth is not None
            views.append((pose, obstacle_scan(depth, Intrinsics())))
    grid, origin = grid_of_views(views, RESOLUTION)
    rows, cols = np.nonzero(grid >= 0)
    x = origin[0] + (cols + 0.5) * RESOLUTION
    y = origin[1] + (rows + 0.5) * RESOLUTION
    near_wall = (x < 0.15) | (x > 5.85) | (y < 0.15) | (y > 3.85)
    outside = (x < 0) | (x > 6) | (y < 0) | (y > 4)
    occupied = grid[rows, cols] == 100
    assert occupied.sum() > 0.9 * (2 * 6 + 2 * 4) / RESOLUTION  # the walls, all round
    assert not (occupied & ~near_wall).any()  # nothing stands in the room
    assert not (~occupied & outside).any()  # nothing seen through the walls
    inside = (x > 0.4) & (x < 5.6) & (y > 0.4) & (y < 3.6)
    assert (grid[rows, cols][inside] == 0).sum() > 0.95 * (5.2 * 3.2) / RESOLUTION**2


def test_what_hangs_above_the_robot_or_lies_on_the_floor_is_no_obstacle() -> None:
    depth = np.full((480, 640), np.nan, np.float32)
    intrinsics = Intrinsics()
    rows = np.arange(480, dtype=np.float32)[:, None]
    below = rows - intrinsics.cy
    with np.errstate(divide="ignore"):
        floor = np.where(below > 0, intrinsics.fy * 0.25 / below, np.nan)  # camera 0.25 m up
    depth[:] = np.where(below > 0, floor, 2.0)[:, :1]  # floor below, a wall 2 m ahead above
    top = int(intrinsics.cy - intrinsics.fy * (0.5 - 0.25) / 2.0) - 1  # wall above 0.5 m
    depth[: top + 1] = 2.0
    depth[top + 1 : 240] = np.nan  # ...and nothing between its top and the robot's height
    scan = obstacle_scan(depth, intrinsics)
    assert np.isnan(scan.ranges).all()  # only the floor and what is above the robot
    depth[200:240] = 2.0  # something 2 m ahead at the camera's height
    scan = obstacle_scan(depth, intrinsics)
    assert np.nanmax(np.abs(scan.ranges * np.cos(scan.angles) - 2.05)) < 0.01


# --- bad input ------------------------------------------------------------------------


def test_bad_frames_are_refused_and_change_nothing() -> None:
    poses = [compose(START, (0.1 * i, 0.0, 0.0)) for i in range(4)]
    good = frames(poses)
    mapper = VisualMapper(default_vocabulary(), START)
    for frame in good[:3]:
        mapper.add(frame)
    before = (mapper.state(), mapper.pose, mapper.stats.frames)
    late = Frame(good[1].stamp, good[3].image, good[3].depth, Intrinsics())
    with pytest.raises(KeyframeError, match="in order"):
        mapper.add(late)
    with pytest.raises(KeyframeError, match="must match"):
        mapper.add(Frame(good[3].stamp, good[3].image, good[3].depth[::2, ::2], Intrinsics()))
    assert (mapper.state(), mapper.pose, mapper.stats.frames) == before
    assert mapper.stats.refused == 2
    mapper.add(good[3])  # the stream goes on
    assert mapper.stats.frames == 4


def depth_message(depth: np.ndarray, stamp: float) -> dict[str, Any]:
    return dict(messages.depth_image("camera_optical_frame", depth, stamp))


def raw_32fc1(depth: np.ndarray, stamp: float) -> dict[str, Any]:
    message = depth_message(depth, stamp)
    message.update(
        encoding="32FC1",
        step=depth.shape[1] * 4,
        data=base64.b64encode(depth.astype("<f4").tobytes()).decode(),
    )
    return message


def test_depth_that_is_not_finite_or_does_not_match_the_image_is_refused() -> None:
    ((image, depth),) = rendered([START], 1)
    picture = image_message(image, 5.0)
    depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    assert frame_of(picture, raw_32fc1(depth, 5.0), None, None, 10**6).depth.shape == (480, 640)
    holed = depth.copy()
    holed[10, 10] = np.nan
    holed[20, 20] = np.inf
    with pytest.raises(KeyframeError, match="2 readings are not finite"):
        frame_of(picture, raw_32fc1(holed, 5.0), None, None, 10**6)
    with pytest.raises(KeyframeError, match="does not match"):
        frame_of(picture, depth_message(depth[::2, ::2], 5.0), None, None, 10**6)


# --- a session through the runner ---------------------------------------------------------


def camera_messages(poses: list[Pose]) -> list[tuple[dict[str, Any], ...]]:
    """What a camera-only robot publishes for each pose: image, compressedDepth,
    camera_info, all of one stamp."""
    out: list[tuple[dict[str, Any], ...]] = []
    calibration = pinhole_calibration(CameraModel())
    for index, (image, depth) in enumerate(rendered(poses, 1)):
        stamp = 50.0 + 0.2 * index
        info = messages.camera_info("camera_optical_frame", calibration, stamp)
        depth_msg = messages.compressed_depth("camera_optical_frame", depth, stamp)
        out.append((image_message(image, stamp), dict(depth_msg), dict(info)))
    return out


def _visual_setup() -> tuple[MappingSession, User, Building]:
    from maps.mapping import sessions
    from tests.conftest import make_building, make_user

    admin = make_user("admin", "admin")
    building = make_building(members=[admin])
    robot = make_robot(name="r1", buildings=[building])[0]
    make_robot(name="r2", buildings=[building])
    online(robot)
    session = sessions.start(robot, building, "CorridorV", admin, kind=MappingSession.VISUAL)
    MappingSession.objects.filter(pk=session.pk).update(
        start_x=START[0], start_y=START[1], start_yaw=START[2]
    )
    return session, admin, building


@pytest.mark.django_db(transaction=True)
async def test_a_visual_session_maps_from_camera_frames_and_a_robot_wakes_up_on_its_published_map(
    monkeypatch,
) -> None:
    monkeypatch.setattr(mapping_runner, "SAVE_EVERY", 0.2)
    session, admin, building = await sync_to_async(_visual_setup)()
    client = await sync_to_async(client_for)(admin)
    ahead = [compose(START, (0.1 * i, 0.0, 0.0)) for i in range(16)]
    turning = [compose(ahead[-1], (0.0, 0.0, math.radians(10.0 * k))) for k in range(1, 10)]
    sent = camera_messages(ahead + turning)
    hub = FakeHub("r1", "r2")
    runner = MappingRunner(hub)
    await runner.sync()
    assert set(hub.taps) == {
        "/r1/camera/image/compressed",
        "/r1/camera/depth/image/compressedDepth",
        "/r1/camera/camera_info",
        "/r1/odom",
        "/r2/camera/depth/image/compressedDepth",  # r2 has no session: told if it streams
    }
    worker = runner.workers[session.pk]
    for index, (image, depth, info) in enumerate(sent):
        hub.send("/r2/camera/image/compressed", image)  # a robot with no session: not taken
        hub.send("/r1/camera/camera_info", info)
        hub.send("/r1/camera/image/compressed", image)
        if index == 5:  # an old frame again: out of order, refused
            hub.send("/r1/camera/image/compressed", sent[2][0])
            hub.send("/r1/camera/depth/image/compressedDepth", sent[2][1])
        hub.send("/r1/camera/depth/image/compressedDepth", depth)
        await _drained(worker)
    await _until(lambda: _session(session.pk).stats.get("frames", 0) == len(sent))
    live = await sync_to_async(_session)(session.pk)
    assert live.stats["refused"] == 1
    assert "in order" in live.stats["refusal"]
    assert live.stats["lost"] == 0
    assert live.stats["keyframes"] >= 6
    assert math.dist(live.stats["pose"][:2], ahead[-1][:2]) < 0.1
    grid = (await sync_to_async(client.get)(f"{SESSIONS}{session.pk}/grid")).json()
    assert 100 in grid["data"]
    assert 0 in grid["data"]

    await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/finish")
    await runner.sync()
    published = await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/publish")
    assert published.status_code == 201
    made = await SubMap.objects.aget(building=building, code="CorridorV")
    stored = [k async for k in Keyframe.objects.filter(submap=made)]
    assert len(stored) >= 6
    assert {k.robot for k in stored} == {"r1"}
    assert not await Keyframe.objects.exclude(submap=made).aexists()  # r2 gave nothing
    mapped = stored_keyframes(bytes((await sync_to_async(_session)(session.pk)).keyframes))
    assert len(stored) == len(thinned(mapped))  # what bench visual-slam wakes up on

    # Issue 27 point 3: the published keyframes are the sub-map's relocalisation map at
    # once. A view from between two mapped spots, with other sensor noise, is placed.
    where = compose(ahead[7], (0.04, 0.02, math.radians(2.0)))
    view = Camera(demo_world(seed=1), seed=9).render(where)
    body = {"images": [image_message(view, 60.0)]}
    answer = (await sync_to_async(client.post)("/api/relocalise", body, format="json")).json()
    assert answer["localised"], answer
    assert answer["map_id"] == f"{building.code}/CorridorV"
    placed = answer["pose"]
    assert math.hypot(placed["x"] - where[0], placed["y"] - where[1]) <= 0.25
    assert abs(math.remainder(placed["yaw"] - where[2], math.tau)) <= math.radians(5.0)


def test_a_visual_map_resumes_from_its_saved_state_and_places_the_next_frame() -> None:
    poses = [compose(START, (0.1 * i, 0.0, 0.0)) for i in range(8)]
    given = frames(poses)
    mapper = VisualMapper(default_vocabulary(), START)
    for frame in given[:7]:
        mapper.add(frame)
    again = VisualMapper.resumed(mapper.state(), default_vocabulary())
    assert again.path == mapper.path
    assert len(again.scans) == len(mapper.scans) >= 2
    with pytest.raises(KeyframeError, match="in order"):
        again.add(given[6])  # already mapped before the stop
    again.add(given[7])
    assert again.stats.relocalised == 1  # searched against every keyframe, as a wake-up
    assert math.dist(again.pose[:2], poses[7][:2]) < 0.05


def stamped(stamp: float) -> dict[str, Any]:
    return {"header": {"stamp": {"sec": int(stamp), "nanosec": round(stamp % 1 * 1e9)}}}


def test_frames_beyond_the_queue_drop_the_oldest_and_the_session_says_so() -> None:
    session = MappingSession(pk=1, robot=Robot(name="r1"), kind=MappingSession.VISUAL)
    worker = mapping_runner.worker_for(session)
    assert isinstance(worker, mapping_runner.VisualWorker)
    for index in range(10):
        worker.on_depth(stamped(10 + index))  # depth first, then its image: either order
        worker.on_image(stamped(10 + index))
    worker.on_image(stamped(30))  # an image whose depth never comes: not a frame
    assert len(worker.queue) == mapping_runner.QUEUE_FRAMES
    assert worker.dropped == 10 - mapping_runner.QUEUE_FRAMES
    assert worker.queue[0][1] == stamped(10 + 10 - mapping_runner.QUEUE_FRAMES)
    assert "6 frames dropped" in worker._figures()["behind"]
    worker.on_image({"format": "jpeg"})  # no stamp: pairs with nothing, refused at once
    assert worker.bad_input == 1
    assert "no header.stamp" in worker.refusal


@pytest.mark.slow
def test_a_tour_out_and_back_closes_a_loop_and_its_grid_agrees_with_the_building() -> None:
    poses = corridor_tour(length=3.0, step=0.1, turn=math.radians(10.0))
    mapper = VisualMapper(default_vocabulary(), START)
    for index, frame in enumerate(frames(poses)):
        mapper.add(frame)
        if index % 10 == 0:
            mapper.grid()  # as the session saves it: keyframes added as they come
    assert mapper.stats.loop_closures >= 1
    assert mapper.stats.lost == 0
    assert math.dist(mapper.pose[:2], poses[-1][:2]) < 0.03
    grid, origin = mapper.grid()  # made again from the keyframes the loop moved
    building = demo_building()
    truth = building.world
    rows, cols = np.nonzero(grid >= 0)
    x = origin[0] + (cols + 0.5) * building.resolution
    y = origin[1] + (rows + 0.5) * building.resolution
    truth_rows = np.floor((y - building.world_origin[1]) / building.resolution).astype(int)
    truth_cols = np.floor((x - building.world_origin[0]) / building.resolution).astype(int)
    assert ((truth_rows >= 0) & (truth_cols >= 0)).all()
    expected = truth[truth_rows, truth_cols]
    both = expected >= 0
    agreement = (grid[rows, cols][both] == expected[both]).mean()
    assert both.sum() > 5000  # the corridor, metres of it
    assert agreement > 0.95  # the rest: walls found half a cell to one side


def test_the_grid_is_made_again_only_when_keyframes_moved_past_the_tolerance() -> None:
    poses = [compose(START, (0.1 * i, 0.0, 0.0)) for i in range(12)]
    mapper = VisualMapper(default_vocabulary(), START)
    for frame in frames(poses):
        mapper.add(frame)
    assert mapper.stats.keyframes >= 3
    first, origin = mapper.grid()

    def shift_keyframes(by: float) -> None:  # as a loop closure moves them
        graph = mapper.slam._graph
        graph.keyframes = [_moved(k, compose(k.pose, (by, 0.0, 0.0))) for k in graph.keyframes]

    shift_keyframes(GRID_TOLERANCE[0] / 2)
    kept, kept_origin = mapper.grid()
    assert kept_origin == origin
    assert np.array_equal(kept, first)  # within the tolerance: the grid as it was
    shift_keyframes(0.1)
    moved, moved_origin = mapper.grid()
    views = list(zip(mapper.path, mapper.scans, strict=True))
    fresh, fresh_origin = grid_of_views(views, mapper.resolution)
    assert not np.array_equal(moved, first)
    assert moved_origin == fresh_origin
    assert np.array_equal(moved, fresh)  # past it: made again at the keyframes' poses


def test_a_session_started_facing_the_demos_plain_wall_maps_on_and_counts_its_restarts() -> None:
    start = demo_building().robot_starts[0]
    poses = [compose(start, (0.0, 0.0, math.radians(10.0 * k))) for k in range(19)]
    mapper = VisualMapper(default_vocabulary(), start)
    for frame, odometry in zip(frames(poses), poses, strict=True):
        mapper.add(replace(frame, odometry=odometry))
    assert mapper.stats.restarted >= 1  # lost on the wall, then on from odometry's pose
    assert mapper.stats.tracked + mapper.stats.relocalised > 5  # not only the first frame
    assert mapper.stats.keyframes == len(mapper.keyframes()) == len(mapper.scans) > 3
