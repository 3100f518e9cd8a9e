"""A WebRTC session ends when the access it was opened with is revoked, as ``/stream``
does: the WHEP offer goes through the real ASGI application, the peer lives on."""

from __future__ import annotations

from typing import Any

import pytest
from aiortc import RTCPeerConnection
from asgiref.testing import ApplicationCommunicator
from channels.db import database_sync_to_async

from robots.services import rotate_token
from telemetry.video.relay import get_video_relay
from telemetry.video.webrtc import sessions_of
from tests.conftest import make_building, make_robot
from tests.fixtures_live import until
from tests.support.http_scopes import http_scope

pytestmark = pytest.mark.django_db(transaction=True)

TOPIC = "/r1/camera/image/compressed"
WAIT = 10.0


async def post_offer(token: str, sdp: str) -> dict[str, Any]:
    from cloudnav_web.asgi import application

    headers = {"Authorization": f"Token {token}", "Content-Type": "application/sdp"}
    scope = http_scope("/whep", {"topic": TOPIC}, headers) | {"method": "POST"}
    app = ApplicationCommunicator(application, scope)
    await app.send_input({"type": "http.request", "body": sdp.encode(), "more_body": False})
    start = await app.receive_output(WAIT)
    await app.receive_output(WAIT)  # the answer
    await app.wait(WAIT)
    return dict(start)


async def test_a_session_ends_when_the_robots_token_is_rotated(rosbridge: Any) -> None:
    building = await database_sync_to_async(make_building)()
    record, token = await database_sync_to_async(make_robot)(name="r1", buildings=[building])
    await rosbridge(token=token)  # starts this process's hub
    peer = RTCPeerConnection()
    peer.addTransceiver("video", direction="recvonly")
    await peer.setLocalDescription(await peer.createOffer())
    try:
        start = await post_offer(token, peer.localDescription.sdp)
        assert start["status"] == 201
        sessions = sessions_of(await get_video_relay())
        assert len(sessions.sessions) == 1
        await database_sync_to_async(rotate_token)(record)
        await until(lambda: not sessions.sessions, "the session to end", 2.0)
    finally:
        await peer.close()
