"""The server's life: a viewer leaving a stream, and SIGTERM with streams open, leave no
traceback (over real sockets against daphne)."""

from __future__ import annotations

import asyncio
import signal

import pytest

from tests.conftest import make_building, make_robot
from tests.support.camera_streams import jpeg, watch

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def token() -> str:
    return make_robot(name="r1", buildings=[make_building()])[1]


@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
async def test_a_viewer_leaving_a_stream_logs_no_traceback(daphne_server, token, kind):
    camera, stream = await watch(daphne_server, token, kind)
    stream.close()
    for _ in range(10):  # frames after the viewer left: the stream notices and ends
        await camera.send(jpeg())
        await asyncio.sleep(0.05)
    await camera.close()
    await asyncio.sleep(0.5)
    assert "Traceback" not in daphne_server.log()


@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
async def test_sigterm_with_a_stream_open_exits_cleanly(daphne_server, token, kind):
    camera, stream = await watch(daphne_server, token, kind)
    daphne_server.process.send_signal(signal.SIGTERM)
    code = await asyncio.to_thread(daphne_server.process.wait, 15)
    stream.close()
    await camera.close()
    log = daphne_server.log()
    assert code == 0, log
    assert "Traceback" not in log
    assert "Segmentation fault" not in log
