"""A live WebM stream written by hand: an init segment, then one Cluster per frame.

PyAV's WebM muxer, even with ``live=1`` and ``cluster_time_limit=0``, closes a Cluster only
when the next frame arrives, so every frame would leave one frame late (200 ms at 5 Hz).
The format a live stream needs is small (Matroska's EBML, WebM subset), so it is written
here and each frame leaves the moment it is encoded:

- the init segment: the EBML header, a Segment of unknown size (it never ends), its Info
  (millisecond timestamps) and Tracks (one VP8 video track);
- per frame, a Cluster of known size holding its Timestamp and one BlockGroup: the
  frame's Block, its BlockDuration and, unless it is a keyframe, a ReferenceBlock.

Why every frame declares a duration: a frame alone in its Cluster has none a demuxer could
infer, so Chromium gives it a default of 63 ms, and the Media Source coded frame
processing algorithm takes a frame that comes more than twice the previous frame's
duration after it as a discontinuity and drops every frame until the next keyframe. A
5 frames/s camera (200 ms apart) then showed one picture per keyframe interval. So each
frame declares the longest recent interval between arrivals (``FrameClock``), and a frame
that still comes too late for the frame before it (a camera that paused) is encoded as a
keyframe (``LiveWebm.continues``), so no player has anything to drop.

``LiveWebm`` keeps the Clusters since the last keyframe. A viewer who joins late (or falls
a whole keyframe interval behind) gets them in one go, re-timed a millisecond apart and
ending at the newest frame's time, so a player decodes them at once and plays from now
instead of a keyframe interval behind; Media Source Extensions in ``sequence`` mode and a
plain ``<video>`` both accept this.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

# Element IDs (Matroska specification), with their marker bits, as written.
EBML = b"\x1a\x45\xdf\xa3"
EBML_VERSION = b"\x42\x86"
EBML_READ_VERSION = b"\x42\xf7"
EBML_MAX_ID_LENGTH = b"\x42\xf2"
EBML_MAX_SIZE_LENGTH = b"\x42\xf3"
DOC_TYPE = b"\x42\x82"
DOC_TYPE_VERSION = b"\x42\x87"
DOC_TYPE_READ_VERSION = b"\x42\x85"
SEGMENT = b"\x18\x53\x80\x67"
INFO = b"\x15\x49\xa9\x66"
TIMESTAMP_SCALE = b"\x2a\xd7\xb1"
MUXING_APP = b"\x4d\x80"
WRITING_APP = b"\x57\x41"
TITLE = b"\x7b\xa9"
DATE_UTC = b"\x44\x61"
TRACKS = b"\x16\x54\xae\x6b"
TRACK_ENTRY = b"\xae"
TRACK_NUMBER = b"\xd7"
TRACK_UID = b"\x73\xc5"
TRACK_TYPE = b"\x83"
FLAG_LACING = b"\x9c"
CODEC_ID = b"\x86"
VIDEO = b"\xe0"
PIXEL_WIDTH = b"\xb0"
PIXEL_HEIGHT = b"\xba"
CLUSTER = b"\x1f\x43\xb6\x75"
TIMESTAMP = b"\xe7"
SIMPLE_BLOCK = b"\xa3"
BLOCK_GROUP = b"\xa0"
BLOCK = b"\xa1"
BLOCK_DURATION = b"\x9b"
REFERENCE_BLOCK = b"\xfb"

UNKNOWN_SIZE = b"\x01\xff\xff\xff\xff\xff\xff\xff"
TRACK = 1
MATROSKA_EPOCH = 978_307_200  # 2001-01-01T00:00:00 UTC in Unix seconds
KEYFRAME_FLAG = 0x80
APP = "CloudNav video relay"
DEFAULT_FRAME_MS = 100
"""A frame's declared duration until two frames have shown the camera's rate."""
RATE_MEMORY = 8
"""How many of the latest intervals between frames a declared duration covers."""


def size_vint(size: int) -> bytes:
    """Return ``size`` as an EBML variable-length integer of the fewest bytes."""
    for length in range(1, 9):
        if size < (1 << (7 * length)) - 1:  # all ones is reserved for "unknown"
            return (size | (1 << (7 * length))).to_bytes(length, "big")
    raise ValueError(f"{size} is too large for an EBML size")


def element(element_id: bytes, payload: bytes) -> bytes:
    return element_id + size_vint(len(payload)) + payload


def uint(element_id: bytes, value: int) -> bytes:
    return element(element_id, value.to_bytes(max(1, (value.bit_length() + 7) // 8), "big"))


def text(element_id: bytes, value: str) -> bytes:
    return element(element_id, value.encode("utf-8"))


def date(element_id: bytes, unix_seconds: float) -> bytes:
    """A Matroska date: signed nanoseconds since 2001-01-01T00:00:00 UTC."""
    nanoseconds = round((unix_seconds - MATROSKA_EPOCH) * 1e9)
    return element(element_id, nanoseconds.to_bytes(8, "big", signed=True))


def init_segment(width: int, height: int, title: str = "", epoch: float | None = None) -> bytes:
    """Return the stream's start: EBML header, open Segment, Info and one VP8 track.

    ``epoch`` (Unix seconds) is the wall-clock time of stream time 0, written as the
    Segment's DateUTC, so a viewer can tell when each frame reached the server.
    """
    tracks = element(TRACKS, _vp8_track(width, height))
    return _ebml_header() + SEGMENT + UNKNOWN_SIZE + _info(title, epoch) + tracks


def _ebml_header() -> bytes:
    return element(
        EBML,
        uint(EBML_VERSION, 1)
        + uint(EBML_READ_VERSION, 1)
        + uint(EBML_MAX_ID_LENGTH, 4)
        + uint(EBML_MAX_SIZE_LENGTH, 8)
        + text(DOC_TYPE, "webm")
        + uint(DOC_TYPE_VERSION, 2)  # SimpleBlock needs version 2
        + uint(DOC_TYPE_READ_VERSION, 2),
    )


def _info(title: str, epoch: float | None) -> bytes:
    return element(
        INFO,
        uint(TIMESTAMP_SCALE, 1_000_000)  # timestamps in milliseconds
        + text(MUXING_APP, APP)
        + text(WRITING_APP, APP)
        + (text(TITLE, title) if title else b"")
        + (date(DATE_UTC, epoch) if epoch is not None else b""),
    )


def _vp8_track(width: int, height: int) -> bytes:
    return element(
        TRACK_ENTRY,
        uint(TRACK_NUMBER, TRACK)
        + uint(TRACK_UID, TRACK)
        + uint(TRACK_TYPE, 1)  # video
        + uint(FLAG_LACING, 0)
        + text(CODEC_ID, "V_VP8")
        + element(VIDEO, uint(PIXEL_WIDTH, width) + uint(PIXEL_HEIGHT, height)),
    )


def sint(element_id: bytes, value: int) -> bytes:
    """A signed integer element, two's complement in the fewest bytes."""
    length = max(1, (value.bit_length() + 8) // 8)
    return element(element_id, value.to_bytes(length, "big", signed=True))


def cluster(
    timestamp_ms: int, frame: bytes, keyframe: bool, duration_ms: int, reference_ms: int = 1
) -> bytes:
    """Return one frame as a Cluster at ``timestamp_ms`` holding one BlockGroup that
    declares its duration; a frame that is not a keyframe references the frame
    ``reference_ms`` before it (Matroska's way of saying it depends on another)."""
    block = bytes((0x80 | TRACK, 0, 0, 0)) + frame
    group = element(BLOCK, block) + uint(BLOCK_DURATION, max(1, duration_ms))
    if not keyframe:
        group += sint(REFERENCE_BLOCK, -max(1, reference_ms))
    return element(CLUSTER, uint(TIMESTAMP, timestamp_ms) + element(BLOCK_GROUP, group))


@dataclass
class FrameClock:
    """Stream times and declared durations of live frames, from when they arrived.

    A frame's time is milliseconds since the first one arrived (strictly increasing); its
    declared duration is the longest of the last ``RATE_MEMORY`` intervals between
    arrivals, so the next frame of a steady or jittery camera is never more than twice as
    far (see the module's docstring). ``epoch`` is the first arrival (Unix seconds).
    """

    epoch: float | None = None
    _last: int = -1
    _intervals: deque[int] = field(default_factory=lambda: deque(maxlen=RATE_MEMORY))

    def time_of(self, received: float) -> tuple[int, int]:
        """Return ``(timestamp, duration)`` in ms of a frame that arrived at ``received``."""
        if self.epoch is None:
            self.epoch = received
        timestamp = max(self._last + 1, round((received - self.epoch) * 1000))
        if self._last >= 0:
            self._intervals.append(timestamp - self._last)
        self._last = timestamp
        return timestamp, max(self._intervals, default=DEFAULT_FRAME_MS)


@dataclass(frozen=True, slots=True)
class EncodedFrame:
    """One encoded video frame: its bytes, whether it is a keyframe, its stream time (ms),
    the camera frame's stamp and arrival time (seconds) for the delay statistics, and its
    declared duration (ms)."""

    data: bytes
    keyframe: bool
    timestamp: int
    origin: float
    received: float
    duration: int = DEFAULT_FRAME_MS


@dataclass(frozen=True, slots=True)
class Chunk:
    """What one viewer is sent in one write: the bytes, the frames in them, the cursor to
    read from next, and how many frames the viewer skipped to get here."""

    data: bytes
    frames: tuple[EncodedFrame, ...]
    cursor: int
    skipped: int


class LiveWebm:
    """One endless WebM stream shared by every viewer, with its current keyframe interval.

    Frames are numbered from 0 as they are appended; a viewer keeps the number of the next
    frame it needs (its cursor). Memory holds the init segment and the frames since the
    last keyframe, however many viewers there are and however slowly they read.
    """

    def __init__(
        self, width: int, height: int, title: str = "", epoch: float | None = None
    ) -> None:
        self.width = width
        self.height = height
        self.init = init_segment(width, height, title, epoch)
        self._frames: list[EncodedFrame] = []
        self._clusters: list[bytes] = []
        self._first = 0  # the number of self._frames[0], a keyframe
        self.next = 0  # the number the next appended frame gets
        self.nbytes = 0  # bytes of the clusters held

    def append(self, frame: EncodedFrame) -> bytes:
        """Add the next frame; a keyframe starts a new interval. Returns its Cluster.

        Raises ValueError for a first frame that is not a keyframe: nobody could decode it.
        """
        previous = self._frames[-1].timestamp if self._frames else frame.timestamp - 1
        if frame.keyframe:
            self._frames, self._clusters = [], []
            self._first, self.nbytes = self.next, 0
        elif not self._frames:
            raise ValueError("a live WebM stream must start with a keyframe")
        data = cluster(
            frame.timestamp, frame.data, frame.keyframe, frame.duration, frame.timestamp - previous
        )
        self._frames.append(frame)
        self._clusters.append(data)
        self.nbytes += len(data)
        self.next += 1
        return data

    def continues(self, timestamp: int) -> bool:
        """Whether a frame at ``timestamp`` follows the newest one closely enough (within
        twice its declared duration) for a Media Source player to keep decoding; a frame
        that does not must be a keyframe, or the player drops it and all that follow it
        until the next keyframe."""
        if not self._frames:
            return False
        newest = self._frames[-1]
        return timestamp - newest.timestamp <= 2 * newest.duration

    @property
    def started(self) -> bool:
        """True once a keyframe arrived, so a viewer can start."""
        return bool(self._frames)

    def join(self) -> Chunk:
        """Return a new viewer's start: the init segment and the interval so far, re-timed."""
        caught_up = self.catch_up()
        return Chunk(self.init + caught_up.data, caught_up.frames, caught_up.cursor, 0)

    def read(self, cursor: int) -> Chunk:
        """Return the frames from ``cursor`` on. A viewer whose cursor fell out of the
        current interval skips to its keyframe (re-timed, see the module's docstring)."""
        if cursor < self._first:
            caught_up = self.catch_up()
            return Chunk(caught_up.data, caught_up.frames, self.next, self._first - cursor)
        start = cursor - self._first
        frames = tuple(self._frames[start:])
        return Chunk(b"".join(self._clusters[start:]), frames, self.next, 0)

    def catch_up(self) -> Chunk:
        """Return the current interval as Clusters a millisecond apart, ending at the newest
        frame's time, so a player shows the newest frame at once."""
        frames = tuple(self._frames)
        if not frames:
            return Chunk(b"", (), self.next, 0)
        newest, last = frames[-1].timestamp, len(frames) - 1
        data = b"".join(
            cluster(newest - (last - i), f.data, f.keyframe, f.duration if i == last else 1)
            for i, f in enumerate(frames)
        )
        return Chunk(data, frames, self.next, 0)
