"""WebRTC video requests and their encoders: what ``/whep?topic=T`` asks for, and the one
encoder per camera and parameter set whose packets every viewer of it is sent.

A WHEP request names the codec (``type=vp8|h264``, VP8 by default), the ``bitrate`` in
bit/s, the output ``width``/``height`` (as ``/stream``: absent keeps the camera's) and an
optional frame rate cap ``fps``. Equal requests give equal ``StreamParams``, so the relay
shares one pipeline between them.

Encoders are tuned for delay: no B-frames or look-ahead, one slice, a keyframe every
``gop`` frames so a viewer that lost packets recovers on its own (a shared encoder cannot
answer each viewer's picture loss indication with a keyframe of its own).

No Django here: this module is part of the domain layer.
"""

from __future__ import annotations

from collections.abc import Mapping
from fractions import Fraction

import av

from .video import (
    BadFrame,
    BadStreamParam,
    ImageParams,
    StreamParams,
    StreamRequest,
    UnknownStream,
    Vp8Params,
    int_param,
    side_param,
)
from .vp8 import NOMINAL_RATE, Vp8Encoder

WEBRTC_VP8 = "webrtc/vp8"
WEBRTC_H264 = "webrtc/h264"
CODECS = {"vp8": WEBRTC_VP8, "h264": WEBRTC_H264}
MIME_TYPES = {WEBRTC_VP8: "video/VP8", WEBRTC_H264: "video/H264"}
# Under the 1 Mbit/s a teleoperation link is given for 640x480 at 30 frames/s.
DEFAULT_RTC_BITRATE = 800_000
MIN_RTC_BITRATE = 50_000
MAX_RTC_BITRATE = 20_000_000
# Two seconds at 30 frames/s: how long a viewer that lost a packet may wait for a keyframe.
RTC_GOP = 60
# libvpx's quantiser range for live WebRTC (libwebrtc uses 2..56).
RTC_QMIN = 4
RTC_QMAX = 56
MAX_FPS = 60


def parse_whep_request(query: Mapping[str, str]) -> StreamRequest:
    """Return the stream a ``/whep`` query asks for.

    Raises UnknownStream for a missing topic or an unknown ``type``, BadStreamParam for a
    malformed or out-of-range parameter.
    """
    topic = query.get("topic", "")
    if not topic:
        raise UnknownStream("no topic was given")
    codec = (query.get("type") or "vp8").lower()
    if codec not in CODECS:
        raise UnknownStream(f"unknown WebRTC codec {codec!r} (vp8 or h264)")
    bitrate = int_param(query, "bitrate", MIN_RTC_BITRATE, MAX_RTC_BITRATE) or DEFAULT_RTC_BITRATE
    encoder = Vp8Params(bitrate=bitrate, qmin=RTC_QMIN, qmax=RTC_QMAX, gop=RTC_GOP)
    image = ImageParams(width=side_param(query, "width"), height=side_param(query, "height"))
    fps = int_param(query, "fps", 1, MAX_FPS)
    return StreamRequest(topic, StreamParams(CODECS[codec], image, encoder, fps))


def new_encoder(params: StreamParams) -> Vp8Encoder:
    """Return the encoder of a WebRTC stream's ``params``. Raises BadStreamParam for a
    stream that is not WebRTC."""
    if params.vp8 is None or params.type not in MIME_TYPES:
        raise BadStreamParam(f"{params.type} is not a WebRTC stream")
    if params.type == WEBRTC_H264:
        return H264Encoder(params.vp8, params.image)
    return Vp8Encoder(params.vp8, params.image)


class H264Encoder(Vp8Encoder):
    """The same live encoder with libx264 (constrained baseline, as every browser decodes
    it): frames in, Annex B packets out, the keyframes carrying SPS and PPS."""

    def _codec_context(self, size: tuple[int, int]) -> av.VideoCodecContext:
        context = av.CodecContext.create("libx264", "w")
        assert isinstance(context, av.VideoCodecContext)  # libx264 is a video codec
        context.width, context.height = size
        context.pix_fmt = "yuv420p"
        context.time_base = Fraction(1, 1000)
        context.framerate = Fraction(NOMINAL_RATE, 1)
        context.bit_rate = self.params.bitrate
        context.gop_size = self.params.gop
        context.max_b_frames = 0
        # Without a global header flag libx264 repeats SPS and PPS before every keyframe.
        context.options = {
            "preset": "ultrafast",
            "tune": "zerolatency",
            "profile": "baseline",
            "threads": "1",
        }
        try:
            context.open()
        except av.error.FFmpegError as error:
            raise BadFrame(f"libx264 refused the settings: {error}") from None
        return context


# NAL unit types that start a picture a decoder can begin with: IDR slice, SPS.
_KEY_NAL_TYPES = {5, 7}


def h264_keyframe(access_unit: bytes) -> bool:
    """True if an Annex B H.264 access unit holds an IDR slice or a sequence parameter set
    (a viewer can start decoding there)."""
    for chunk in access_unit.split(b"\x00\x00\x01")[1:]:
        if chunk and chunk[0] & 0x1F in _KEY_NAL_TYPES:
            return True
    return False
