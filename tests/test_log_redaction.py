"""Robot tokens never appear in the server's output: access log, logs and tracebacks
(a real daphne, whose stdout and stderr are its log)."""

from __future__ import annotations

import asyncio
import logging
import urllib.error
import urllib.request

import pytest
import websockets

from cloudnav_web.redaction import RedactingFilter
from tests.conftest import make_building, make_robot

pytestmark = pytest.mark.django_db(transaction=True)

UNKNOWN = "cnr_not-a-token-anyone-has"


def get(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return int(response.status)
    except urllib.error.HTTPError as error:
        return error.code


@pytest.fixture
def token() -> str:
    return make_robot(name="r1", buildings=[make_building()])[1]


async def test_no_token_reaches_the_servers_output(daphne_server, token):
    server = daphne_server
    async with websockets.connect(server.rosbridge_url(token)) as ws:
        await ws.send('{"op": "subscribe", "topic": "pose"}')
    with pytest.raises(websockets.InvalidStatus):
        async with websockets.connect(server.rosbridge_url(UNKNOWN)):
            pass
    for secret in (token, UNKNOWN):
        url = f"{server.url}/stream?topic=/r2/camera/image/compressed&token={secret}"
        await asyncio.to_thread(get, url)
    await asyncio.sleep(0.3)
    log = server.log()
    assert "token=[redacted]" in log
    assert token not in log
    assert UNKNOWN not in log


def test_the_log_filter_redacts_messages_and_tracebacks():
    try:
        raise ValueError("bad url /rosbridge?token=cnr_secret123")
    except ValueError as error:
        exc_info = (type(error), error, error.__traceback__)
        record = logging.LogRecord(
            "x", logging.ERROR, __file__, 1, "failed: %s", (str(error),), exc_info
        )
    RedactingFilter().filter(record)
    text = logging.Formatter().format(record)
    assert "cnr_secret123" not in text
    assert "token=[redacted]" in text
