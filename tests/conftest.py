"""Personas and builders shared by the tests.

Personas: ``admin``, ``operator`` and ``viewer`` are members of their group and of the
building they are given; ``outsider`` is a signed-in user with no group and no building.
Builders take keyword arguments and fill the rest with ``kwargs.setdefault``.
"""

from __future__ import annotations

import io
from collections.abc import AsyncIterator
from typing import Any

import httpx
import numpy as np
import pytest
from django.contrib.auth.models import Group, User
from PIL import Image
from rest_framework.test import APIClient

from cloudnav_web import background
from maps import services
from maps.domain.mapfile import load_map_upload
from maps.models import Building, EnvironmentalTag, SubMap
from robots.models import Robot
from robots.services import register_robot
from telemetry.domain.bus import OnMessage, Topic, TopicTap

# Fixtures that several test files share and conftest does not hold: the live servers, the
# scaled mode's two rosbridge processes (``cluster``, ``connect``), the ROS 2 installs
# (``ros2_venv``) and the demo's robots seeded with their tokens (``tokens``).
pytest_plugins = [
    "tests.fixtures_live",
    "tests.support.scaled_rosbridge",
    "tests.support.ros2",
    "tests.support.demo_operator",
]

# Fixtures that start real server, agent or browser processes: a test that asks for one,
# directly or through another fixture, is marked ``live``. A test whose database writes
# other threads must see (``transactional_db``: the in-process rosbridge and video tests)
# is marked ``transactional``. ``make unit`` leaves both out.
LIVE_FIXTURES = frozenset({"daphne_server", "daphne_servers", "scaled_servers", "demo"})


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        fixtures = set(getattr(item, "fixturenames", ()))
        if fixtures & LIVE_FIXTURES:
            item.add_marker(pytest.mark.live)
        database = item.get_closest_marker("django_db")
        if "transactional_db" in fixtures or (database and database.kwargs.get("transaction")):
            item.add_marker(pytest.mark.transactional)


@pytest.fixture(scope="session", autouse=True)
def serving_workers() -> None:
    """The workers that serve requests, started as the server starts them: tests call the
    views without the ASGI application (``cloudnav_web.background``)."""
    background.start_serving()


def make_user(username: str, group: str | None = None, **kwargs: Any) -> User:
    kwargs.setdefault("password", "pw-" + username)
    user = User.objects.create_user(username=username, **kwargs)
    if group:
        user.groups.add(Group.objects.get_or_create(name=group)[0])
    return user


def make_building(**kwargs: Any) -> Building:
    kwargs.setdefault("code", "boccioni_1")
    kwargs.setdefault("name", "Boccioni building")
    kwargs.setdefault("zip_code", "56037")
    members = kwargs.pop("members", ())
    building = Building.objects.create(**kwargs)
    building.members.add(*members)
    return building


def map_pgm(width: int = 40, height: int = 30, wall: int = 0, free: int = 254) -> bytes:
    """A map_saver style PGM: free inside, a one-pixel wall around, 205 in the top-left corner."""
    pixels = np.full((height, width), free, np.uint8)
    pixels[0, :] = pixels[-1, :] = pixels[:, 0] = pixels[:, -1] = wall
    pixels[1:4, 1:4] = 205
    out = io.BytesIO()
    Image.fromarray(pixels, "L").save(out, "PPM")
    return out.getvalue()


def map_yaml(**kwargs: Any) -> bytes:
    kwargs.setdefault("image", "map.pgm")
    kwargs.setdefault("resolution", 0.05)
    kwargs.setdefault("origin", [0.0, 0.0, 0.0])
    kwargs.setdefault("occupied_thresh", 0.65)
    kwargs.setdefault("free_thresh", 0.196)
    kwargs.setdefault("negate", 0)
    return "".join(f"{key}: {value}\n" for key, value in kwargs.items()).encode()


def make_submap(building: Building, **kwargs: Any) -> SubMap:
    kwargs.setdefault("code", "CorridorA")
    image = kwargs.pop("image", None) or map_pgm()
    yaml = kwargs.pop("yaml", None) or map_yaml()
    loaded = load_map_upload(yaml, {"map.pgm": image}, 10**7)
    submap, _ = services.save_submap(building, kwargs.pop("code"), loaded, **kwargs)
    return submap


def make_tag(submap: SubMap, **kwargs: Any) -> EnvironmentalTag:
    kwargs.setdefault("marker_id", submap.building.tags.count())
    kwargs.setdefault("x", 1.0)
    kwargs.setdefault("y", 0.5)
    kwargs.setdefault("yaw", 0.0)
    kwargs.setdefault("links_to", submap)
    return EnvironmentalTag.objects.create(building=submap.building, submap=submap, **kwargs)


def make_robot(**kwargs: Any) -> tuple[Robot, str]:
    """Register a robot and return it with its token."""
    kwargs.setdefault("name", "r1")
    return register_robot(**kwargs)


class FakeHub:
    """The two things the mapping and upkeep runners ask of a hub: the robots connected
    here, and taps (``hub.tap``); ``send`` is a robot publishing, ``taps`` what is tapped."""

    def __init__(self, *robots: str) -> None:
        self.here = set(robots)
        self.taps: dict[str | None, list[TopicTap]] = {}

    def robots(self) -> set[str]:
        return set(self.here)

    def tap(self, topic: str, on_message: OnMessage) -> TopicTap:
        tap = TopicTap(self.taps, topic, on_message)
        self.taps.setdefault(topic, []).append(tap)
        return tap

    def send(self, topic: str, msg: dict[str, Any]) -> None:
        for tap in list(self.taps.get(topic, [])):
            tap.on_message(Topic(topic, None), msg)


@pytest.fixture
def admin(db: None) -> User:
    return make_user("admin", "admin")


@pytest.fixture
def operator(db: None) -> User:
    return make_user("operator", "operator")


@pytest.fixture
def viewer(db: None) -> User:
    return make_user("viewer", "viewer")


@pytest.fixture
def outsider(db: None) -> User:
    return make_user("outsider")


@pytest.fixture
def building(admin: User, operator: User, viewer: User) -> Building:
    return make_building(members=[admin, operator, viewer])


@pytest.fixture
def token(building: Building) -> str:
    """The token of robot ``r1``, a member of ``building``."""
    return make_robot(name="r1", buildings=[building])[1]


@pytest.fixture
def second_operator(building: Building) -> User:
    """``operator2``, a second operator of ``building``."""
    user = make_user("operator2", "operator")
    building.members.add(user)
    return user


@pytest.fixture
async def cloud(demo_token: str) -> AsyncIterator[httpx.AsyncClient]:
    """HTTP to the real application, in-process, with the demo robot's token
    (``demo_token``, in ``tests.fixtures_live``)."""
    from cloudnav_web.asgi import application

    async with httpx.AsyncClient(
        transport=httpx.ASGITransport(app=application),
        base_url="http://testserver",
        headers={"Authorization": f"Token {demo_token}"},
    ) as http:
        yield http


def client_for(principal: User | str | None) -> APIClient:
    """An API client signed in as a user, or carrying a robot token (a str)."""
    client = APIClient()
    if isinstance(principal, User):
        client.force_login(principal)
    elif isinstance(principal, str):
        client.credentials(HTTP_AUTHORIZATION=f"Token {principal}")
    return client
