"""The 3D maps of visual sessions: a known room's coloured cloud lies on its walls, floor
and ceiling and reads back as PLY (``plyfile``), its OctoMap has its walls occupied and
its middle free (read back by ``pyoctomap``), and a session's maps are downloaded so far,
fed to the live view, and published beside the sub-map version."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import plyfile
import pyoctomap
import pytest
from django.contrib.auth.models import User

from benchmarks.visual_tracking import START
from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.se2 import Pose, compose
from maps.domain.visual_cloud import (
    VOXEL,
    KeyframeCloud,
    feed_bytes,
    keyframe_cloud,
    map_cloud,
    octomap_bytes,
    ply_bytes,
)
from maps.domain.visual_mapping import VisualMapper, colour_of, stored_view
from maps.domain.vocabulary import default_vocabulary
from maps.mapping import sessions
from maps.models import MappingSession
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import world_from_grid
from tests.conftest import client_for, make_building, make_robot, make_submap, make_user
from tests.support.mapping_sessions import online
from tests.support.visual_room import RESOLUTION, frames, image_message, known_room

SESSIONS = "/api/mapping/sessions/"
WALL_HEIGHT = 2.43  # metres: the simulated world's ceiling, as the camera renders it


def room_views() -> tuple[list[KeyframeCloud], list[Pose]]:
    camera = Camera(world_from_grid(known_room(), (0.0, 0.0), RESOLUTION), seed=1)
    clouds, poses = [], []
    for at_x, at_y in [(1.5, 2.0), (3.0, 2.0), (4.5, 2.0)]:
        for k in range(12):
            pose = (at_x, at_y, k * math.pi / 6)
            image, depth = camera.capture(pose)
            assert depth is not None
            clouds.append(keyframe_cloud(depth, Intrinsics(), Mount(), None, image))
            poses.append(pose)
    return clouds, poses


def test_a_known_rooms_cloud_lies_on_its_surfaces_one_point_a_voxel_and_reads_as_ply() -> None:
    clouds, poses = room_views()
    data = ply_bytes(map_cloud(clouds, poses))
    read = plyfile.PlyData.read(io.BytesIO(data))
    vertex = read["vertex"]
    assert [p.name for p in vertex.properties] == ["x", "y", "z", "red", "green", "blue"]
    points = np.stack([vertex["x"], vertex["y"], vertex["z"]], axis=1)
    x, y, z = points.T
    to_surface = np.min(
        np.abs([x - 0.05, x - 5.95, y - 0.05, y - 3.95, z, z - WALL_HEIGHT]), axis=0
    )  # the wall cells' inner faces, the floor and the ceiling
    assert np.percentile(to_surface, 99) < 0.03
    assert to_surface.max() < 0.05
    cubes = np.floor(points / VOXEL).astype(np.int64)
    assert len(np.unique(cubes, axis=0)) > 0.9 * len(points)  # thinned, not piled up
    area = 2 * (6 + 4) * WALL_HEIGHT + 2 * 6 * 4
    assert 0.3 * area / VOXEL**2 < len(points) < 1.5 * area / VOXEL**2
    assert len(data) < 20 * len(points) + 300  # 15 bytes a point and the header


def test_a_keyframe_cloud_takes_its_colours_from_the_colour_image() -> None:
    depth = np.full((480, 640), 2.0, np.float32)
    depth[:, :320] = np.nan  # half the view saw nothing: no points there
    colour = np.zeros((120, 160, 3), np.uint8)
    colour[:] = (200, 30, 10)
    cloud = keyframe_cloud(depth, Intrinsics(), Mount(), colour)
    assert len(cloud) > 100
    assert (cloud.colours == (200, 30, 10)).all()
    assert np.allclose(cloud.points[:, 0], 2.05, atol=0.03)  # 2 m ahead of a camera 5 cm on
    assert (cloud.points[:, 1] < 0.03).all()  # all on the right half of the view


def test_only_keyframes_colours_are_decoded_and_colour_their_clouds() -> None:
    asked = []

    def red() -> np.ndarray:
        asked.append(1)
        return np.full((120, 160, 3), (220, 20, 20), np.uint8)

    mapper = VisualMapper(default_vocabulary(), START)
    for frame in frames([compose(START, (0.05 * i, 0.0, 0.0)) for i in range(10)]):
        mapper.add(frame, red)
    assert len(asked) == mapper.stats.keyframes < mapper.stats.frames
    assert all((cloud.colours == (220, 20, 20)).all() for cloud in mapper.clouds)


def test_a_frames_colours_are_its_jpeg_at_a_quarter_size_or_none() -> None:
    picture = np.zeros((480, 640, 3), np.uint8)
    picture[:, :, 2] = 250  # red, as OpenCV orders a colour image's channels (BGR)
    colours = colour_of(image_message(picture, 5.0), 10**6)()
    assert colours is not None
    assert colours.shape == (120, 160, 3)
    assert np.abs(colours.astype(int) - (250, 0, 0)).max() < 8  # RGB, JPEG's rounding
    assert colour_of({"data": "not base64!"}, 10**6)() is None  # grey points then


def octree_of(data: bytes, tmp_path: Path) -> pyoctomap.OcTree:
    path = tmp_path / "map.bt"
    path.write_bytes(data)
    tree = pyoctomap.OcTree(0.1)
    assert tree.readBinary(str(path))
    return tree


def occupied(tree: pyoctomap.OcTree, x: float, y: float, z: float) -> bool | None:
    """True, False, or None where the map knows nothing."""
    node = tree.search(np.array([x, y, z]))
    return None if node is None else bool(tree.isNodeOccupied(node))


def test_a_known_rooms_octomap_has_its_walls_occupied_and_its_middle_free(tmp_path) -> None:
    clouds, poses = room_views()
    tree = octree_of(octomap_bytes(clouds, poses, Mount()), tmp_path)
    assert tree.getResolution() == pytest.approx(0.05)
    along = np.linspace(0.5, 3.5, 7)
    # Each wall's face (0.05 m in from the room's edge) as the voxels either side of it,
    # at heights the views saw (the camera sees 1.2 m high at 2 m).
    walls = [((0.025, y, 0.9), (0.075, y, 0.9)) for y in along]
    walls += [((5.925, y, 0.5), (5.975, y, 0.5)) for y in along]
    walls += [((x, 0.025, 0.6), (x, 0.075, 0.6)) for x in np.linspace(0.5, 5.5, 9)]
    walls += [((x, 3.925, 0.9), (x, 3.975, 0.9)) for x in np.linspace(0.5, 5.5, 9)]
    found = [occupied(tree, *a) or occupied(tree, *b) for a, b in walls]
    assert found == [True] * len(walls)
    inside = [(x, y, z) for x in (1.0, 3.0, 5.0) for y in (1.0, 2.0, 3.0) for z in (0.3, 0.6)]
    assert [occupied(tree, *p) for p in inside] == [False] * len(inside)
    assert occupied(tree, -0.5, 2.0, 1.0) is None  # behind a wall: never seen


# --- a session's maps ---------------------------------------------------------------------


def mapped() -> VisualMapper:
    ahead = [compose(START, (0.1 * i, 0.0, 0.0)) for i in range(8)]
    turning = [compose(ahead[-1], (0.0, 0.0, math.radians(10.0 * k))) for k in range(1, 6)]
    mapper = VisualMapper(default_vocabulary(), START)
    for frame in frames(ahead + turning):
        mapper.add(frame)
    assert mapper.stats.keyframes >= 4
    return mapper


@pytest.fixture(scope="module")
def saved_state() -> bytes:
    return mapped().state()


def test_a_resumed_mapper_keeps_its_keyframes_clouds(saved_state: bytes) -> None:
    again = VisualMapper.resumed(saved_state, default_vocabulary())
    view = stored_view(saved_state)
    assert len(again.clouds) == len(view.clouds) == len(view.poses) == again.stats.keyframes
    for kept, saved in zip(again.clouds, view.clouds, strict=True):
        assert np.array_equal(kept.colours, saved.colours)
        assert np.abs(kept.points - saved.points).max() < 0.005  # float16 in the state


def body(answer: Any) -> bytes:
    """A heavy answer's body: streamed under daphne, whole under the test client."""
    return b"".join(answer.streaming_content) if answer.streaming else answer.content


def visual_session(admin: User, keyframes: bytes, state: str) -> MappingSession:
    building = make_building(members=[admin])
    robot = make_robot(name="r1", buildings=[building])[0]
    online(robot)
    session = sessions.start(robot, building, "RoomV", admin, kind=MappingSession.VISUAL)
    MappingSession.objects.filter(pk=session.pk).update(keyframes=keyframes, state=state)
    return MappingSession.objects.get(pk=session.pk)


@pytest.mark.django_db
def test_a_sessions_3d_maps_so_far_download_and_feed_the_live_view(saved_state: bytes) -> None:
    admin = make_user("admin", "admin")
    session = visual_session(admin, saved_state, MappingSession.RUNNING)
    client = client_for(admin)
    answer = client.get(f"{SESSIONS}{session.pk}/cloud.ply")
    assert answer.status_code == 200
    assert "mapping_" in answer["Content-Disposition"]
    cloud = plyfile.PlyData.read(io.BytesIO(body(answer)))
    assert cloud["vertex"].count > 1000
    answer = client.get(f"{SESSIONS}{session.pk}/octomap.bt")
    assert body(answer).startswith(b"# Octomap OcTree binary file")

    view = stored_view(saved_state)
    feed = client.get(f"{SESSIONS}{session.pk}/points?from=1")
    assert feed.content == feed_bytes(view.clouds, view.poses, view.loops, 1)
    keyframes, start, sent, loops = np.frombuffer(feed.content[:16], "<i4")
    assert (keyframes, start, loops) == (len(view.poses), 1, len(view.loops))
    assert sent == min(8, keyframes - 1)
    poses = np.frombuffer(feed.content[16 : 16 + 12 * keyframes], "<f4").reshape(-1, 3)
    assert np.allclose(poses, view.poses, atol=1e-5)
    first = 16 + 12 * keyframes + 8 * loops
    (count,) = np.frombuffer(feed.content[first : first + 4], "<i4")
    points = np.frombuffer(feed.content[first + 4 : first + 4 + 12 * count], "<f4")
    assert np.allclose(points.reshape(-1, 3), view.clouds[1].points)
    for bad in ("-1", "x", "1e3"):
        assert client.get(f"{SESSIONS}{session.pk}/points?from={bad}").status_code == 400


@pytest.mark.django_db
def test_publishing_keeps_the_3d_maps_beside_the_version(saved_state: bytes, settings, tmp_path):
    settings.CLOUDNAV_MAP3D_DIR = tmp_path / "maps3d"
    settings.CLOUDNAV_KEYFRAME_DIR = tmp_path / "keyframes"
    admin = make_user("admin", "admin")
    session = visual_session(admin, saved_state, MappingSession.RUNNING)
    client = client_for(admin)
    before = body(client.get(f"{SESSIONS}{session.pk}/cloud.ply"))
    MappingSession.objects.filter(pk=session.pk).update(
        state=MappingSession.FINISHED, grid_pgm=b"P5\n2 2\n255\n\xfe\xfe\x00\xfe"
    )
    published = client.post(f"{SESSIONS}{session.pk}/publish")
    assert published.status_code == 201, published.content
    version = f"/api/buildings/{session.building.code}/maps/RoomV/versions/1"
    answer = client.get(f"{version}/cloud.ply")
    assert answer.status_code == 200
    assert answer.content == before
    octomap = client.get(f"{version}/octomap.bt").content
    assert octomap.startswith(b"# Octomap OcTree binary file")
    assert not list((tmp_path / "maps3d").rglob(".*"))  # no temporary file left
    assert client.get(version.replace("/1", "/2") + "/cloud.ply").status_code == 404


@pytest.mark.django_db
def test_a_laser_version_or_session_has_no_3d_map(saved_state: bytes) -> None:
    admin = make_user("admin", "admin")
    session = visual_session(admin, b"", MappingSession.RUNNING)
    other = make_submap(session.building, code="Uploaded")  # from a map_server pair
    version = f"/api/buildings/{session.building.code}/maps/{other.code}/versions/1"
    assert client_for(admin).get(f"{version}/octomap.bt").status_code == 404
    MappingSession.objects.filter(pk=session.pk).update(kind=MappingSession.LASER)
    client = client_for(admin)
    assert client.get(f"{SESSIONS}{session.pk}/cloud.ply").status_code == 409
    assert client.get(f"{SESSIONS}{session.pk}/points").status_code == 409


@pytest.mark.django_db
def test_it_rejects_outsider(saved_state: bytes, outsider: User) -> None:
    admin = make_user("admin", "admin")
    session = visual_session(admin, saved_state, MappingSession.RUNNING)
    for path in ("cloud.ply", "octomap.bt", "points"):
        assert client_for(outsider).get(f"{SESSIONS}{session.pk}/{path}").status_code == 404
        assert client_for(None).get(f"{SESSIONS}{session.pk}/{path}").status_code in (401, 403)
