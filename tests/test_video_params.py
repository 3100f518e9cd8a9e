"""Stream requests parse as web_video_server's query strings, and camera frames as
rosbridge carries them (base64 in JSON, bytes in CBOR)."""

from __future__ import annotations

import base64

import pytest

from telemetry.domain.video import (
    DEFAULT_BITRATE,
    BadFrame,
    BadStreamParam,
    ImageParams,
    StreamParams,
    UnknownStream,
    Vp8Params,
    camera_topic_candidates,
    frame_from_message,
    parse_stream_request,
)

JPEG = b"\xff\xd8\xff\xe0 not really a jpeg"
STAMPED = {"header": {"stamp": {"sec": 10, "nanosec": 500_000_000}}, "format": "jpeg"}


def test_it_defaults_to_mjpeg_with_the_robots_own_bytes():
    asked = parse_stream_request({"topic": "/r1/camera/image/compressed"})
    assert asked.params == StreamParams("mjpeg")
    assert asked.params.image.untouched


def test_it_reads_web_video_server_image_parameters():
    query = {"topic": "/t", "type": "mjpeg", "quality": "90", "width": "240", "height": "-1"}
    params = parse_stream_request(query).params
    assert params.image == ImageParams(quality=90, width=240, height=None)
    assert parse_stream_request({"topic": "/t", "invert": ""}).params.image.invert


def test_it_reads_vp8_encoder_parameters_with_their_defaults():
    params = parse_stream_request({"topic": "/t", "type": "vp8", "gop": "50"}).params
    assert params.vp8 == Vp8Params(bitrate=DEFAULT_BITRATE, qmin=10, qmax=42, gop=50)
    assert params.image.quality is None  # VP8's quality is libvpx's deadline, not JPEG's


def test_equal_requests_share_parameters_and_different_ones_do_not():
    one = parse_stream_request({"topic": "/t", "quality": "80"}).params
    same = parse_stream_request({"topic": "/t", "quality": "80", "width": ""}).params
    other = parse_stream_request({"topic": "/t", "quality": "81"}).params
    assert one == same
    assert hash(one) == hash(same)
    assert one != other


def test_ros_compressed_ignores_image_parameters_as_web_video_server_does():
    params = parse_stream_request({"topic": "/t", "type": "ros_compressed", "quality": "5"}).params
    assert params == StreamParams("ros_compressed")


@pytest.mark.parametrize("kind", ["png", "h264", "vp9", "anything"])
def test_it_rejects_unknown_types(kind):
    with pytest.raises(UnknownStream):
        parse_stream_request({"topic": "/t", "type": kind})


def test_it_rejects_a_missing_topic():
    with pytest.raises(UnknownStream):
        parse_stream_request({"type": "mjpeg"})


@pytest.mark.parametrize(
    "query",
    [
        {"quality": "0"},
        {"quality": "high"},
        {"width": "99999"},
        {"type": "vp8", "qmin": "50", "qmax": "10"},
        {"type": "vp8", "gop": "100000"},
        {"type": "vp8", "quality": "fastest"},
    ],
)
def test_it_rejects_parameters_out_of_range(query):
    with pytest.raises(BadStreamParam):
        parse_stream_request({"topic": "/t", **query})


def test_a_base_topic_also_means_its_compressed_topic():
    assert camera_topic_candidates("/r1/camera/image") == [
        "/r1/camera/image/compressed",
        "/r1/camera/image",
    ]
    assert camera_topic_candidates("/r1/camera/image/compressed") == ["/r1/camera/image/compressed"]


@pytest.mark.parametrize(
    "data", [base64.b64encode(JPEG).decode(), JPEG, list(JPEG)], ids=["json", "cbor", "list"]
)
def test_a_frame_comes_from_any_encoding_of_the_data(data):
    frame = frame_from_message({**STAMPED, "data": data}, received=11.0)
    assert frame.data == JPEG
    assert frame.stamp == 10.5
    assert frame.content_type == "image/jpeg"
    assert frame.is_jpeg
    assert frame.origin_time == 10.5


def test_a_frame_without_a_stamp_counts_from_its_arrival():
    frame = frame_from_message({"format": "jpeg", "data": JPEG}, received=11.0)
    assert frame.stamp is None
    assert frame.origin_time == 11.0


@pytest.mark.parametrize(
    "msg",
    [
        {"format": "jpeg"},
        {"format": "jpeg", "data": "not base64!"},
        {"format": "rgb8", "data": JPEG},
        {"format": "jpeg", "data": 42},
    ],
)
def test_it_refuses_what_is_not_an_image(msg):
    with pytest.raises(BadFrame):
        frame_from_message(msg)
