"""Who may open which camera's streams, snapshots, viewer page and statistics, asked
through the real ASGI application by every persona.

Expected: members of the robot's building (admin, operator, viewer) watch it; an outsider
is told it does not exist (404); a robot watches its own camera only (403 for another's);
no credential or a bad token gets 401; an unknown topic or stream type is a 404.
"""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from django.contrib.auth.models import User

from telemetry.domain.video import parse_stream_request
from telemetry.video.relay import get_video_relay
from tests.conftest import make_building, make_robot, make_user
from tests.fixtures_live import session_cookie
from tests.support.http_scopes import Answer, get

pytestmark = pytest.mark.django_db(transaction=True)

CAMERA = "/r1/camera/image/compressed"


@dataclass
class World:
    credentials: dict[str, dict[str, str]]


@pytest.fixture
def world(admin: User, operator: User, viewer: User, outsider: User) -> World:
    building = make_building(members=[admin, operator, viewer])
    other = make_building(code="other_1", members=[make_user("other_viewer", "viewer")])
    _, own = make_robot(name="r1", buildings=[building])
    _, foreign = make_robot(name="r2", buildings=[other])
    cookies = {
        u.username: {"Cookie": session_cookie(u).decode()}
        for u in (admin, operator, viewer, outsider)
    }
    return World(
        {
            **cookies,
            "robot": {"Authorization": f"Token {own}"},
            "robot_in_query": {"token": own},
            "other_robot": {"Authorization": f"Token {foreign}"},
            "bad_token": {"Authorization": "Token cnr_not-a-token"},
            "anonymous": {},
        }
    )


async def ask(world: World, who: str, path: str, **query: str) -> Answer:
    credential = dict(world.credentials[who])
    token = credential.pop("token", None)
    if token is not None:
        query["token"] = token
    return await get(path, query, credential)


EXPECTED = {
    "admin": 200,
    "operator": 200,
    "viewer": 200,
    "outsider": 404,
    "robot": 200,
    "robot_in_query": 200,
    "other_robot": 403,
    "bad_token": 401,
    "anonymous": 401,
}


@pytest.mark.parametrize("kind", ["mjpeg", "vp8", "ros_compressed"])
@pytest.mark.parametrize("who", list(EXPECTED))
async def test_every_persona_gets_its_answer_for_a_stream(world, who, kind):
    answer = await ask(world, who, "/stream", topic=CAMERA, type=kind)
    assert answer.status == EXPECTED[who], answer.body


async def test_it_rejects_outsider(world):
    for path in ("/stream", "/snapshot", "/stream_viewer"):
        answer = await ask(world, "outsider", path, topic=CAMERA)
        assert answer.status == 404, path
    listing = await ask(world, "outsider", "/video/")
    assert CAMERA not in listing.body.decode()


async def test_a_stream_answers_in_web_video_server_format(world):
    answer = await ask(world, "viewer", "/stream", topic=CAMERA, type="mjpeg")
    assert answer.headers["content-type"] == "multipart/x-mixed-replace;boundary=boundarydonotcross"
    assert answer.headers["cache-control"].startswith("no-cache, no-store")
    vp8 = await ask(world, "viewer", "/stream", topic=CAMERA, type="vp8")
    assert vp8.headers["content-type"] == "video/webm"


async def test_the_base_topic_names_its_compressed_camera_as_in_web_video_server(world):
    answer = await ask(world, "viewer", "/stream", topic="/r1/camera/image", type="ros_compressed")
    assert answer.status == 200


@pytest.mark.parametrize(
    "query",
    [
        {"topic": "/r1/pose"},  # not images
        {"topic": "/nobody/camera/image/compressed"},  # no such robot
        {"topic": "not a name"},
        {"topic": CAMERA, "type": "png"},
        {"topic": CAMERA, "type": "h264"},
        {},
    ],
)
async def test_an_unknown_topic_or_type_is_a_404(world, query):
    assert (await ask(world, "admin", "/stream", **query)).status == 404


async def test_a_bad_parameter_is_a_400(world):
    answer = await ask(world, "viewer", "/stream", topic=CAMERA, quality="500")
    assert answer.status == 400
    assert b"quality" in answer.body


async def test_a_missing_credential_asks_for_a_token(world):
    answer = await ask(world, "anonymous", "/snapshot", topic=CAMERA)
    assert answer.status == 401
    assert answer.headers["www-authenticate"] == "Token"


async def test_people_are_sent_to_sign_in_for_the_pages(world):
    for path in ("/stream_viewer", "/video/"):
        answer = await ask(world, "anonymous", path, topic=CAMERA)
        assert answer.status == 302
        assert "/accounts/login/" in answer.headers["location"]


@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
async def test_the_viewer_page_shows_the_stream(world, kind):
    answer = await ask(world, "viewer", "/stream_viewer", topic=CAMERA, type=kind)
    assert answer.status == 200
    page = answer.body.decode()
    assert f"<title>{CAMERA}</title>" in page
    tag = '<video id="stream"' if kind == "vp8" else '<img id="stream"'
    assert tag in page
    assert "/stream?topic=" in page


async def test_the_camera_page_lists_the_cameras_a_person_may_watch(world):
    for who in ("admin", "viewer"):
        page = (await ask(world, who, "/video/")).body.decode()
        assert CAMERA in page
        assert "/r2/camera" not in page


async def test_statistics_show_only_the_cameras_one_may_watch(world):
    relay = await get_video_relay()
    mjpeg = parse_stream_request({"topic": CAMERA}).params
    vp8 = parse_stream_request({"topic": CAMERA, "type": "vp8"}).params
    async with relay.watch(CAMERA, mjpeg), relay.watch("/r2/camera/image/compressed", vp8):
        seen = {
            who: (await ask(world, who, "/api/video/stats")).json()
            for who in ("viewer", "outsider", "robot")
        }
    assert {s["topic"] for s in seen["viewer"]["streams"]} == {CAMERA}
    assert {s["type"] for s in seen["viewer"]["streams"]} == {"mjpeg", "source"}
    assert seen["outsider"]["streams"] == []
    assert {s["topic"] for s in seen["robot"]["streams"]} == {CAMERA}
    assert (await ask(world, "anonymous", "/api/video/stats")).status == 401
    assert relay.pipelines == {}
    assert relay.feeds == {}


async def test_statistics_asked_with_a_streams_query_are_that_streams_only(world):
    relay = await get_video_relay()
    mjpeg = parse_stream_request({"topic": CAMERA}).params
    vp8 = parse_stream_request({"topic": CAMERA, "type": "vp8"}).params
    small_vp8 = parse_stream_request({"topic": CAMERA, "type": "vp8", "width": "160"}).params
    async with relay.watch(CAMERA, mjpeg), relay.watch(CAMERA, vp8), relay.watch(CAMERA, small_vp8):
        playing = (await ask(world, "viewer", "/api/video/stats", topic=CAMERA, type="vp8")).json()
        source = (
            await ask(world, "viewer", "/api/video/stats", topic=CAMERA, type="source")
        ).json()
        bad = await ask(world, "viewer", "/api/video/stats", topic=CAMERA, type="vp8", gop="x")
    [stream] = playing["streams"]
    assert (stream["type"], stream["params"]) == ("vp8", vp8.label())
    assert [s["type"] for s in source["streams"]] == ["source"]
    assert bad.status == 400
