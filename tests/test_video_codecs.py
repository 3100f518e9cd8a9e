"""The wire formats and codecs of the relays, without a server: multipart parts as
web_video_server writes them, JPEG re-encoding, and the live WebM stream decoded by PyAV,
from the start and for a viewer who joins late."""

from __future__ import annotations

import io
import time
from itertools import pairwise

import av
import cv2
import numpy as np
import pytest

from telemetry.domain import jpeg, multipart
from telemetry.domain.video import Frame, ImageParams, Vp8Params
from telemetry.domain.video_stats import StreamStats, percentile
from telemetry.domain.vp8 import Vp8Encoder
from telemetry.domain.webm import (
    EncodedFrame,
    FrameClock,
    LiveWebm,
    size_vint,
)
from tests.support.webm_reader import WebmReader

WIDTH, HEIGHT = 160, 96


def picture(i: int, width: int = WIDTH, height: int = HEIGHT) -> bytes:
    image = np.full((height, width, 3), 90, np.uint8)
    cv2.circle(image, (10 + 3 * i % width, height // 2), 12, (0, 0, 230), -1)
    return bytes(cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes())


def camera_frame(i: int) -> Frame:
    return Frame(picture(i), "jpeg", 100.0 + i / 30, 100.0 + i / 30)


# ---------------------------------------------------------------- multipart


def test_a_part_is_framed_as_web_video_server_frames_it():
    part = multipart.part(b"JPEGDATA", "image/jpeg", 1712345678.1234567)
    assert part == (
        b"Content-type: image/jpeg\r\n"
        b"X-Timestamp: 1712345678.123457\r\n"
        b"Content-Length: 8\r\n\r\n"
        b"JPEGDATA\r\n--boundarydonotcross\r\n"
    )
    assert multipart.preamble() == b"--boundarydonotcross\r\n"
    assert multipart.CONTENT_TYPE == "multipart/x-mixed-replace;boundary=boundarydonotcross"


def test_the_part_reader_reads_parts_split_anywhere():
    body = multipart.preamble() + b"".join(
        multipart.part(bytes([i]) * (100 + i), "image/jpeg", float(i)) for i in range(5)
    )
    reader, parts = multipart.PartReader(), []
    for at in range(0, len(body), 37):
        parts += reader.feed(body[at : at + 37])
    assert [len(payload) for _, payload in parts] == [100, 101, 102, 103, 104]
    assert [headers["x-timestamp"] for headers, _ in parts][-1] == "4.000000"


def test_stream_responses_carry_no_cache_headers():
    headers = multipart.stream_headers()
    assert headers["Cache-Control"].startswith("no-cache, no-store, must-revalidate")
    assert headers["Pragma"] == "no-cache"
    assert multipart.video_headers("video/webm")["Expires"] == "0"


# ---------------------------------------------------------------- JPEG


def test_a_reencode_resizes_turns_and_sets_the_quality():
    source = picture(3, 320, 200)
    small = jpeg.reencode(source, ImageParams(quality=50, width=160, height=100), 95)
    assert jpeg.decode(small).shape == (100, 160, 3)
    low = jpeg.reencode(source, ImageParams(quality=10), 95)
    assert len(low) < len(jpeg.reencode(source, ImageParams(quality=95), 95))
    turned = jpeg.decode(jpeg.reencode(source, ImageParams(invert=True), 95))
    upright = jpeg.decode(source)
    assert np.abs(turned.astype(int) - upright[::-1, ::-1].astype(int)).mean() < 4


def test_one_side_alone_keeps_the_other_as_web_video_server_does():
    assert jpeg.output_size((320, 200), 160, None) == (160, 200)


# ---------------------------------------------------------------- VP8 in live WebM


def encode_stream(count: int, gop: int = 10) -> tuple[Vp8Encoder, LiveWebm, list[bytes]]:
    """Encode ``count`` frames; return the encoder, the stream and each append's Cluster."""
    encoder = Vp8Encoder(Vp8Params(gop=gop), ImageParams())
    stream, clusters = None, []
    for i in range(count):
        for encoded in encoder.encode(camera_frame(i), timestamp_ms=33 * i):
            if stream is None:
                assert encoder.size is not None
                stream = LiveWebm(*encoder.size, "/r1/camera/image/compressed", epoch=100.0)
            clusters.append(stream.append(encoded))
    assert stream is not None
    return encoder, stream, clusters


def decode(data: bytes) -> list[av.VideoFrame]:
    with av.open(io.BytesIO(data), mode="r") as container:
        assert isinstance(container, av.container.InputContainer)
        return list(container.decode(video=0))


def test_the_live_stream_decodes_with_pyav_frame_by_frame():
    _, stream, clusters = encode_stream(30)
    frames = decode(stream.init + b"".join(clusters))
    assert len(frames) == 30
    assert (frames[0].width, frames[0].height) == (WIDTH, HEIGHT)
    assert [f.pts for f in frames[:3]] == [0, 33, 66]


def test_a_late_joiner_starts_at_the_last_keyframe_and_plays_at_once():
    _, stream, _ = encode_stream(25, gop=10)  # keyframes at 0, 10, 20
    joined = stream.join()
    assert len(joined.frames) == 5
    assert joined.frames[0].keyframe
    frames = decode(joined.data)
    assert len(frames) == 5
    # re-timed a millisecond apart, ending at the newest frame's time
    assert [f.pts for f in frames] == [33 * 24 - 4 + i for i in range(5)]


def test_a_viewer_that_fell_a_keyframe_interval_behind_skips_to_the_keyframe():
    _, stream, _ = encode_stream(25, gop=10)
    chunk = stream.read(cursor=3)
    assert chunk.skipped == 20 - 3
    assert chunk.frames[0].keyframe
    assert chunk.cursor == 25
    assert stream.read(chunk.cursor).data == b""


def test_memory_holds_one_keyframe_interval_whatever_the_stream_length():
    _, stream, clusters = encode_stream(60, gop=10)
    assert stream.nbytes == sum(len(c) for c in clusters[50:])


def test_the_reader_finds_each_block_and_the_streams_epoch():
    _, stream, clusters = encode_stream(12, gop=10)
    reader = WebmReader()
    body = stream.init + b"".join(clusters)
    blocks = [b for at in range(0, len(body), 100) for b in reader.feed(body[at : at + 100])]
    assert [b.timestamp for b in blocks] == [33 * i for i in range(12)]
    assert [b.keyframe for b in blocks].count(True) == 2
    assert reader.epoch == pytest.approx(100.0)


def test_every_frame_declares_a_duration_that_covers_the_gap_to_the_next():
    # Chromium's Media Source drops every frame that comes more than twice the previous
    # frame's duration after it until the next keyframe; undeclared, a lone frame's
    # duration is 63 ms, so a 5 frames/s camera (200 ms apart) showed only keyframes.
    clock = FrameClock()
    arrivals = [100.0 + 0.2 * i + (0.03 if i % 3 == 0 else 0.0) for i in range(12)]
    times = [clock.time_of(at) for at in arrivals]
    encoder = Vp8Encoder(Vp8Params(gop=100), ImageParams())
    stream, body = None, b""
    for i, (timestamp, duration) in enumerate(times):
        for encoded in encoder.encode(camera_frame(i), timestamp, duration):
            stream = stream or LiveWebm(*(encoder.size or (0, 0)))
            body += stream.append(encoded)
    assert stream is not None
    blocks = WebmReader().feed(stream.init + body)
    assert all(b.duration is not None for b in blocks)
    gaps = [(b.timestamp - a.timestamp, a.duration) for a, b in pairwise(blocks)]
    assert all(gap <= 2 * (duration or 0) for gap, duration in gaps)
    assert [b.keyframe for b in blocks].count(True) == 1
    assert [f.duration for f in decode(stream.init + body)][1:] == [b.duration for b in blocks][1:]


def test_a_frame_after_the_camera_paused_is_a_keyframe_a_player_can_start_from():
    _, stream, _ = encode_stream(5, gop=100)  # 33 ms apart
    newest = stream.join().frames[-1].timestamp
    assert stream.continues(newest + 40)
    assert not stream.continues(newest + 5000)


def test_a_frame_clock_counts_from_the_first_arrival_and_never_goes_back():
    clock = FrameClock()
    assert clock.time_of(50.0) == (0, 100)  # no rate known yet: the default duration
    assert clock.time_of(50.2) == (200, 200)
    assert clock.time_of(50.1) == (201, 200)  # arrivals out of order still move forward
    assert clock.epoch == 50.0


def test_a_stream_must_start_with_a_keyframe():
    with pytest.raises(ValueError, match="keyframe"):
        LiveWebm(2, 2).append(EncodedFrame(b"x", False, 0, 0.0, 0.0))


def test_the_encoder_can_be_told_to_start_a_new_interval():
    encoder, _stream, _ = encode_stream(3, gop=100)
    encoder.force_keyframe()
    (encoded,) = encoder.encode(camera_frame(4), timestamp_ms=200)
    assert encoded.keyframe


def test_vp8_encodes_480x320_in_well_under_a_frame_time():
    encoder = Vp8Encoder(Vp8Params(), ImageParams())
    frames = [Frame(picture(i, 480, 320), "jpeg", None, 0.0) for i in range(30)]
    started = time.process_time()
    for i, frame in enumerate(frames):
        encoder.encode(frame, timestamp_ms=33 * i)
    assert (time.process_time() - started) / len(frames) < 0.010  # measured: about 1.5 ms


def test_ebml_sizes_take_the_fewest_bytes():
    assert size_vint(0) == b"\x80"
    assert size_vint(126) == b"\xfe"
    assert size_vint(127) == b"\x40\x7f"  # 0xff alone would mean "unknown size"


# ---------------------------------------------------------------- statistics


def test_stream_statistics_give_rates_and_delay_percentiles():
    stats = StreamStats(started=0.0)
    for i in range(50):
        now = 1.0 + i / 10
        stats.produced(now, 1000)
        stats.sent(now, [(now - 0.010 - (0.1 if i == 49 else 0), now - 0.002)], 1000)
    figures = stats.snapshot(6.0)
    assert figures["fps"] == pytest.approx(10.0)
    assert figures["kB_per_s"] == pytest.approx(10.0)
    assert figures["delay_p50_ms"] == pytest.approx(10.0)
    assert figures["delay_p99_ms"] == pytest.approx(110.0)
    assert figures["relay_p99_ms"] == pytest.approx(2.0)
    assert figures["clock_offset_ms"] is None
    assert percentile([], 50) is None


def test_stamps_of_a_clock_far_off_the_servers_give_its_offset_not_a_delay():
    stats = StreamStats(started=0.0)
    for i in range(20):
        now = 1.0 + i / 10
        stamp = now - 609.6  # the robot's clock runs ten minutes behind
        stats.sent(now, [(stamp, now - 0.002)], 1000)
    figures = stats.snapshot(3.0)
    assert figures["delay_p50_ms"] is None
    assert figures["delay_p99_ms"] is None
    assert figures["clock_offset_ms"] == pytest.approx(609598.0)
    assert figures["relay_p99_ms"] == pytest.approx(2.0)
