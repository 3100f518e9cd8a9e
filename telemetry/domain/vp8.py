"""A VP8 encoder for live video: PyAV's libvpx, tuned for delay, not for file size.

web_video_server's settings (``bitrate``, ``qmin``, ``qmax``, ``gop``, ``quality`` as the
libvpx deadline) with what live streaming needs on top: no look-ahead or alt-ref frames
(each frame leaves as soon as it is encoded), error resilience, one thread (one camera is
too small to share out, and it keeps the CPU account exact), and ``cpu-used`` 8, which
encodes 480x320 about four times faster than libvpx's default at a similar size.

Input is a camera JPEG, decoded by OpenCV and converted to YUV 4:2:0 (about 0.5 ms for
480x320); libvpx then takes about 1 ms per frame.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import av
import cv2
import numpy as np
from av.video.frame import VideoFrame

from . import jpeg
from .video import BadFrame, Frame, ImageParams, Vp8Params
from .webm import DEFAULT_FRAME_MS, EncodedFrame

CPU_USED = 8
# Frame rate hint for libvpx's rate control; the stream's timestamps are the real times.
NOMINAL_RATE = 30
MILLISECONDS = Fraction(1, 1000)


class Vp8Encoder:
    """Encodes camera frames of one stream to VP8 at a fixed output size.

    The size is fixed by the first frame (or by what ``image`` asks for); later frames of
    another size are scaled to it, so the stream never has to restart.
    """

    def __init__(self, params: Vp8Params, image: ImageParams) -> None:
        self.params = params
        self.image = image
        self.size: tuple[int, int] | None = None
        self._context: av.VideoCodecContext | None = None
        self._force_key = False

    def force_keyframe(self) -> None:
        """Make the next frame a keyframe (when a keyframe interval grew too large)."""
        self._force_key = True

    def encode(
        self, image: Frame, timestamp_ms: int, duration_ms: int = DEFAULT_FRAME_MS
    ) -> list[EncodedFrame]:
        """Encode one camera frame shown at ``timestamp_ms`` for ``duration_ms``; return
        what libvpx gives back: one frame, or none when its rate control drops this one.

        Raises BadFrame if the image cannot be decoded.
        """
        return [
            EncodedFrame(
                bytes(packet),
                bool(packet.is_keyframe),
                timestamp_ms,
                image.origin_time,
                image.received,
                duration_ms,
            )
            for packet in self.packets(image, timestamp_ms)
        ]

    def packets(self, image: Frame, timestamp_ms: int) -> list[av.Packet[Any]]:
        """Encode one camera frame shown at ``timestamp_ms``; return the codec's packets
        (``time_base`` 1/1000 s), as WebRTC senders take them. Raises BadFrame."""
        frame = self._yuv_frame(jpeg.decode(image.data))
        frame.pts = timestamp_ms
        if self._force_key:
            frame.pict_type = av.video.frame.PictureType.I
            self._force_key = False
        packets = self._open(frame).encode(frame)
        for packet in packets:
            packet.time_base = MILLISECONDS
        return packets

    def _yuv_frame(self, pixels: jpeg.Image) -> VideoFrame:
        if self.size is None:
            height, width = pixels.shape[:2]
            width, height = jpeg.output_size((width, height), self.image.width, self.image.height)
            # YUV 4:2:0 halves both sides of the chroma planes: VP8 wants even sides.
            self.size = (width + width % 2, height + height % 2)
        bgr = jpeg.transform(pixels, self.image, self.size)
        yuv = np.asarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420), dtype=np.uint8)
        return VideoFrame.from_ndarray(yuv, format="yuv420p")

    def _open(self, frame: VideoFrame) -> av.VideoCodecContext:
        if self._context is None:
            self._context = self._codec_context((frame.width, frame.height))
        return self._context

    def _codec_context(self, size: tuple[int, int]) -> av.VideoCodecContext:
        return _codec_context(self.params, size)

    def close(self) -> None:
        """Release the encoder; pending frames are dropped (live video has no use for them)."""
        # PyAV frees a codec context when the last reference to it goes.
        self._context = None


def _codec_context(params: Vp8Params, size: tuple[int, int]) -> av.VideoCodecContext:
    context = av.CodecContext.create("libvpx", "w")
    assert isinstance(context, av.VideoCodecContext)  # libvpx is a video codec
    context.width, context.height = size
    context.pix_fmt = "yuv420p"
    context.time_base = MILLISECONDS
    context.framerate = Fraction(NOMINAL_RATE, 1)
    context.bit_rate = params.bitrate
    context.gop_size = params.gop
    context.qmin = params.qmin
    context.qmax = params.qmax
    context.max_b_frames = 0
    context.options = {
        "deadline": params.deadline,
        "cpu-used": str(CPU_USED),
        "lag-in-frames": "0",
        "auto-alt-ref": "0",
        "error-resilient": "1",
        "threads": "1",
    }
    try:
        context.open()
    except av.error.FFmpegError as error:
        raise BadFrame(f"libvpx refused the settings: {error}") from None
    return context
