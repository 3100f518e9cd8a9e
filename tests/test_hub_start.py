"""A process's hub works whatever it served first: an HTTP video request that starts the
hub leaves nothing of its own context in the hub's background work, so a deleted robot is
still cut off (over real sockets against daphne)."""

from __future__ import annotations

import asyncio
import urllib.request

import pytest
import websockets
from django.contrib.auth.models import User

from tests.fixtures_live import LiveServer, session_cookie, video_stats

pytestmark = pytest.mark.django_db(transaction=True)

CSRF = "c" * 32  # a session's unsafe request carries Django's CSRF cookie and the same token


def delete_robot(server: LiveServer, admin: User, name: str) -> int:
    """Delete robot ``name`` through the server's API, as its building's admin would."""
    return delete_with_cookie(server, session_cookie(admin).decode(), name)


def delete_with_cookie(server: LiveServer, session: str, name: str) -> int:
    cookie = f"{session}; csrftoken={CSRF}"
    request = urllib.request.Request(
        f"{server.url}/api/robots/{name}/",
        method="DELETE",
        headers={"Cookie": cookie, "X-CSRFToken": CSRF},
    )
    with urllib.request.urlopen(request, timeout=10) as answer:
        return int(answer.status)


async def closed_within(socket: websockets.ClientConnection, seconds: float) -> bool:
    """True if the server closes ``socket`` within ``seconds`` (frames meanwhile skipped)."""
    try:
        async with asyncio.timeout(seconds):
            async for _ in socket:
                pass
    except TimeoutError:
        return False
    except websockets.ConnectionClosed:
        pass
    return True


@pytest.mark.parametrize("first", ["an HTTP video request", "a robot's socket"])
async def test_a_deleted_robot_is_cut_off_whatever_the_process_served_first(
    daphne_server, admin, token, first
):
    if first == "an HTTP video request":  # the video relay starts the hub
        assert await asyncio.to_thread(video_stats, daphne_server.url, token) == []
    async with websockets.connect(daphne_server.rosbridge_url(token)) as robot:
        await robot.send('{"op": "advertise", "topic": "pose", "type": "geometry_msgs/Pose"}')
        assert await asyncio.to_thread(delete_robot, daphne_server, admin, "r1") == 204
        assert await closed_within(robot, 10.0), daphne_server.log()
    assert "CurrentThreadExecutor" not in daphne_server.log()


ADMIN = """
import django
django.setup()
from maps.models import Building
from tests.conftest import make_user
from tests.fixtures_live import session_cookie
admin = make_user("boss", "admin")
Building.objects.get().members.add(admin)
print(session_cookie(admin).decode())
"""


@pytest.mark.scaled
@pytest.mark.parametrize("first", ["an HTTP video request", "a robot's socket"])
async def test_in_scaled_mode_a_deleted_robot_is_cut_off_whatever_came_first(scaled_servers, first):
    from tests.fixtures_live import run_manage

    cluster = scaled_servers(1)
    live, token = cluster.servers[0], cluster.tokens["r1"]
    cookie = run_manage(cluster.database_url, "-c", ADMIN).strip().splitlines()[-1]
    if first == "an HTTP video request":
        assert await asyncio.to_thread(video_stats, live.url, token) == []
    async with websockets.connect(live.rosbridge_url(token)) as robot:
        await robot.send('{"op": "advertise", "topic": "pose", "type": "geometry_msgs/Pose"}')
        assert await asyncio.to_thread(delete_with_cookie, live, cookie, "r1") == 204
        assert await closed_within(robot, 10.0), live.log()
    assert "CurrentThreadExecutor" not in live.log()
