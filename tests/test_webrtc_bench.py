"""``manage.py bench webrtc`` runs end to end in Chromium: a scratch server, a stamped
camera, each stream type read back in the browser (a short run; the figures themselves
are the bench's to print, the test holds only that each row was measured)."""

from __future__ import annotations

import io
import json
from contextlib import redirect_stdout

import pytest

from benchmarks import webrtc

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_it_prints_delay_frames_bytes_and_encoder_cpu_per_stream_type_read_in_chromium():
    options = {
        "types": "webrtc,mjpeg,vp8",
        "client": "chromium",
        "viewers": 2,
        "duration": 3.0,
        "warmup": 1.0,
        "width": 320,
        "height": 240,
        "rate": 15.0,
        "json": True,
    }
    printed = io.StringIO()
    with redirect_stdout(printed):
        webrtc.run(options)
    result = json.loads(printed.getvalue())
    rows = {row["type"]: row for row in result["rows"]}
    assert set(rows) == {"webrtc/vp8", "mjpeg", "vp8/mse"}
    for row in rows.values():
        assert row["pictures_read"] > 10, row  # time codes read back from the pictures shown
        assert 0 < row["delay_p50_ms"] <= row["delay_p95_ms"], row
        assert row["bytes_per_s_per_viewer"] > 0, row
    assert rows["webrtc/vp8"]["encoder_cpu_core"] > 0
    assert rows["mjpeg"]["encoder_cpu_core"] == 0  # the camera's own JPEG, not decoded
