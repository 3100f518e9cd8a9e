"""The time code survives the relays' codecs: stamped, encoded (JPEG, VP8, H.264 at their
WebRTC bitrate), decoded, and read back exactly."""

from __future__ import annotations

import time

import av
import cv2
import numpy as np
import pytest

from cloudnav_core import timecode
from telemetry.domain.jpeg import decode as jpeg_decode
from telemetry.domain.video import Frame
from telemetry.domain.webrtc import new_encoder, parse_whep_request
from tests.support.camera_feed import camera_frames

NOW = 1_790_000_000_123


def stamped_jpegs(count: int) -> list[bytes]:
    jpegs = []
    for i, jpeg in enumerate(camera_frames(640, 480, quality=80, count=count)):
        image = jpeg_decode(jpeg)
        timecode.stamp(image, NOW + 33 * i)
        jpegs.append(cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes())
    return jpegs


def test_it_reads_back_what_a_jpeg_carries():
    for i, jpeg in enumerate(stamped_jpegs(5)):
        image = jpeg_decode(jpeg)
        assert timecode.read(image) == NOW + 33 * i


@pytest.mark.parametrize("codec", ["vp8", "h264"])
def test_it_reads_back_what_the_webrtc_encoders_carry(codec):
    encoder = new_encoder(parse_whep_request({"topic": "/t", "type": codec}).params)
    decoder = av.CodecContext.create(codec, "r")
    read = []
    for i, jpeg in enumerate(stamped_jpegs(20)):
        for packet in encoder.packets(Frame(jpeg, "jpeg", None, time.time()), 33 * i):
            for frame in decoder.decode(packet):
                read.append(timecode.read(frame.to_ndarray(format="bgr24")))
    assert read == [NOW + 33 * i for i in range(len(read))]
    assert len(read) >= 18


def test_a_picture_without_a_code_is_refused():
    with pytest.raises(timecode.NoTimecode):
        timecode.read(np.full((480, 640, 3), 128, np.uint8))


def test_the_delay_counts_across_the_wrap():
    assert timecode.delay_ms(timecode.MODULO - 10, 30) == 40
