"""Mapping in the server process a robot is connected to, off the relay's hot path.

Each server process runs one ``MappingRunner`` beside its rosbridge hub. Every
``POLL`` seconds it asks the database for the running sessions of the robots connected
to *this* process (in the scaled mode, the robot's process does its mapping, wherever
the session was started) and starts a ``SessionWorker`` for each new one.

A worker taps its robot's topics on the hub (``hub.tap``, the one way to tap the topic
bus, ``telemetry.rosbridge.hub``): a laser session's ``scan`` and ``odom`` (``LaserWorker``), a
visual session's camera image, compressedDepth, camera_info and ``odom``
(``VisualWorker``, which pairs an image and a depth image of one stamp into a frame).
The tap only appends to a bounded queue (``QUEUE_SCANS`` scans, ``QUEUE_FRAMES``
frames; the oldest is dropped, and counted, when SLAM falls behind), so publishing
costs the relay a dict look-up and an append. SLAM (``maps.domain.slam``, or
``maps.domain.visual_mapping``) runs on the queue in a worker thread; every ``SAVE_EVERY``
seconds the map so far, the corrected path, the figures and the keyframes are written to
the session, which is what pages and the API read. Pages are told rather than left to
poll: after each write, and when a worker starts or stops, the runner publishes the
session's id and state on the robot's latched ``mapping`` topic (``std_msgs/String``,
JSON), and a page reads the session again.

A robot that disconnects leaves its session ``interrupted`` with the map so far; a
session finished or discarded meanwhile stops its worker (after a last write for a
finished one, so its candidate map is complete).

Nothing a robot sends stops a worker: a scan that is not a scan (a dict among its
ranges) or a pose beyond the session's extent (``SlamParams.max_extent``) is refused,
counted (``bad_scans``, ``refused``) and said (``refusal``, the last reason) in the
session's figures, and SLAM goes on. Should a worker stop all the same, the runner
notices at its next look and leaves the session ``interrupted`` with the reason, never
``running`` with nobody mapping.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, Protocol

from asgiref.sync import sync_to_async
from django.conf import settings

from cloudnav_core import topics
from cloudnav_core.messages import MappingNews, mapping_message, pose_of
from cloudnav_core.times import stamp_seconds
from cloudnav_core.workers import Inbox, Policy, Pool, TaskWorker
from cloudnav_django.batches import UNREACHABLE
from cloudnav_django.outage import REPORT

from ..domain.slam.mapper import Mapper
from ..domain.slam.params import SlamParams
from ..domain.slam.scans import Scan
from ..domain.visual_mapping import VisualMapper, colour_of, frame_of
from ..domain.vocabulary import default_vocabulary
from ..exceptions import KeyframeError, OutsideExtent
from ..models import MappingSession
from . import sessions

logger = logging.getLogger(__name__)

POLL = 1.0
"""Seconds between the runner's looks at the sessions of this process's robots."""
QUEUE_SCANS = 20
"""Scans waiting for SLAM at most; beyond, the oldest is dropped."""
SAVE_EVERY = 2.0
"""Seconds between writes of the map so far."""

_EXECUTOR = Pool("mapping", 2).executor  # stopped and joined at the end (the registry)


OnMessage = Callable[[Any, dict[str, Any]], None]
"""What a tap calls with each message: the bus's topic (unread here) and the message."""


class Tap(Protocol):
    """A tap of the topic bus (``telemetry.domain.bus.TopicTap``)."""

    def close(self) -> None: ...


class TopicTaps(Protocol):
    """What the runner needs of the hub: the robots connected here and topic taps."""

    def robots(self) -> set[str]: ...

    def tap(self, topic: str, on_message: OnMessage) -> Tap: ...


class SessionWorker(ABC):
    """The mapping of one session, fed by taps on its robot's topics: the taps queue what
    they get (bounded: the oldest is dropped, and counted, when mapping falls behind), a
    worker thread maps the queue, and the map so far is written every ``SAVE_EVERY``
    seconds. ``LaserWorker`` and ``VisualWorker`` say what is tapped, mapped and written."""

    queue_size = QUEUE_SCANS

    def __init__(self, session: MappingSession) -> None:
        self.session_pk = session.pk
        self.robot = session.robot.name
        self.queue: Inbox[Any] = Inbox("mapping", self.queue_size, Policy.DROP_OLDEST)
        self.bad_input = 0
        self.refusal = ""  # why the last input refused was refused
        self.cpu = 0.0
        self._odom: dict[str, Any] | None = None
        self._wake = asyncio.Event()
        self._worker = TaskWorker(f"mapping session {self.session_pk}", self._run)
        self._saved_at = 0.0
        self._started = time.monotonic()
        self.on_saved: Callable[[], None] | None = None
        # Mapping and snapshots take turns: a stopped task's last batch may still be
        # running in its thread when ``stop`` writes the final snapshot.
        self._mapping = threading.Lock()

    # --- the taps: on the hot path, O(1) ----------------------------------------------

    @abstractmethod
    def taps(self) -> list[tuple[str, Callable[[dict[str, Any]], None]]]:
        """``(topic suffix, callback)`` of each topic of the robot the worker is fed by."""
        ...

    def on_odom(self, msg: dict[str, Any]) -> None:
        self._odom = msg

    @property
    def dropped(self) -> int:
        """Items the queue dropped (its oldest) because mapping fell behind."""
        return self.queue.dropped

    def _queue(self, item: Any) -> None:
        self.queue.put(item)
        self._wake.set()

    # --- the work ------------------------------------------------------------------------

    def start(self) -> None:
        self._worker.start()

    @property
    def _task(self) -> asyncio.Task[None] | None:
        return self._worker.task

    @property
    def stopped(self) -> bool:
        """Whether the worker's task ended (it only ends when stopped or broken)."""
        return self._task is not None and self._task.done()

    def why_stopped(self) -> str:
        task = self._task
        if task is None or not task.done():
            return ""
        if task.cancelled():
            return "its worker was cancelled"
        return f"its worker failed: {task.exception()!r}"

    async def stop(self, save: bool = True) -> None:
        task = self._task
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task  # a failure was taken by ``why_stopped``
        if save:
            await self._save()

    async def _run(self) -> None:
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._wake.wait(), SAVE_EVERY)
            self._wake.clear()
            try:
                await self._work()
            except Exception:  # the database away for a moment, or a fault of ours
                logger.exception("mapping session %s: a round failed", self.session_pk)

    async def _work(self) -> None:
        batch = self.queue.take_all()
        if batch:
            await asyncio.get_running_loop().run_in_executor(_EXECUTOR, self._process, batch)
        if time.monotonic() - self._saved_at >= SAVE_EVERY:
            await self._save()

    def _process(self, batch: list[Any]) -> None:
        with self._mapping:
            self._process_locked(batch)

    def _process_locked(self, batch: list[Any]) -> None:
        started = time.thread_time()
        for item in batch:
            try:
                self._add(item)
            except OutsideExtent as error:
                self.refusal = str(error)
            except (ValueError, KeyframeError) as error:
                self.bad_input += 1
                self.refusal = str(error)
        self.cpu += time.thread_time() - started

    @abstractmethod
    def _add(self, item: Any) -> None:
        """Map one queued item. Raises ValueError or KeyframeError for bad input,
        OutsideExtent for a pose beyond the session's extent."""
        ...

    async def _save(self) -> None:
        self._saved_at = time.monotonic()
        loop = asyncio.get_running_loop()
        snapshot = await loop.run_in_executor(_EXECUTOR, self._snapshot)
        if snapshot is None:  # no map yet (no keyframe, nothing to update): figures only
            await sync_to_async(sessions.save_figures)(self.session_pk, self._figures())
        else:
            await sync_to_async(sessions.save_progress)(self.session_pk, *snapshot)
        if self.on_saved is not None:
            self.on_saved()

    def _snapshot(self) -> tuple[Any, ...] | None:
        with self._mapping:
            return self._snapshot_locked()

    def _snapshot_locked(self) -> tuple[Any, ...] | None:
        started = time.thread_time()
        grid, origin = self._grid()
        if not grid.size:
            return None
        state = self._state()
        self.cpu += time.thread_time() - started
        return grid, origin, self._resolution(), self._path(), self._figures(), state

    @abstractmethod
    def _grid(self) -> tuple[Any, tuple[float, float]]: ...

    @abstractmethod
    def _state(self) -> bytes: ...

    @abstractmethod
    def _resolution(self) -> float: ...

    @abstractmethod
    def _path(self) -> list[tuple[float, float, float]]: ...

    @abstractmethod
    def _stats(self) -> dict[str, Any]: ...

    def _figures(self) -> dict[str, Any]:
        elapsed = max(1e-6, time.monotonic() - self._started)
        return {
            **self._stats(),
            "dropped": self.dropped,
            "bad_scans": self.bad_input,
            "refusal": self.refusal,
            "cpu_share": round(self.cpu / elapsed, 4),
        }


class LaserWorker(SessionWorker):
    """2D SLAM (``maps.domain.slam``) on the robot's ``scan`` and ``odom``."""

    def __init__(self, session: MappingSession, prior: Any = None, resume: bytes = b"") -> None:
        super().__init__(session)
        self.params = SlamParams()
        start = (session.start_x, session.start_y, session.start_yaw)
        if resume:
            self.mapper = Mapper.resumed(resume, self.params, prior)
        else:
            self.mapper = Mapper(self.params, start, prior)

    def taps(self) -> list[tuple[str, Callable[[dict[str, Any]], None]]]:
        return [(topics.SCAN, self.on_scan), (topics.ODOM, self.on_odom)]

    def on_scan(self, msg: dict[str, Any]) -> None:
        self._queue((self._odom, msg))

    def _add(self, item: tuple[dict[str, Any] | None, dict[str, Any]]) -> None:
        odom_msg, scan_msg = item
        odom = _odom_pose(odom_msg)
        scan = Scan.from_message(scan_msg, self.params.usable_range)
        if odom is not None:
            self.mapper.add(odom, scan)

    def _grid(self) -> tuple[Any, tuple[float, float]]:
        return self.mapper.grid()

    def _state(self) -> bytes:
        return self.mapper.state()

    def _resolution(self) -> float:
        return self.params.resolution

    def _path(self) -> list[tuple[float, float, float]]:
        return list(self.mapper.path)

    def _stats(self) -> dict[str, Any]:
        return {**self.mapper.stats.__dict__, "pose": list(self.mapper.pose)}


QUEUE_FRAMES = 4
"""Camera frames (image, depth, camera_info) waiting for visual SLAM at most."""
PAIRING = 8
"""Images (and depth images) kept while they wait for the other half of their frame."""


class VisualWorker(SessionWorker):
    """Visual SLAM (``maps.domain.visual_mapping``) on the robot's camera: each colour
    image and the depth image of the same stamp make a frame, with the latest
    ``camera_info`` and ``odom``. A half whose other half does not come within
    ``PAIRING`` frames is forgotten (a robot sends depth with fewer of its images)."""

    queue_size = QUEUE_FRAMES

    def __init__(self, session: MappingSession, resume: bytes = b"") -> None:
        super().__init__(session)
        vocabulary = default_vocabulary()
        if resume:
            self.mapper = VisualMapper.resumed(resume, vocabulary)
        else:
            start = (session.start_x, session.start_y, session.start_yaw)
            self.mapper = VisualMapper(vocabulary, start)
        self._images: dict[float, dict[str, Any]] = {}
        self._depths: dict[float, dict[str, Any]] = {}
        self._info: dict[str, Any] | None = None
        self.max_pixels = settings.CLOUDNAV_MAX_IMAGE_PIXELS

    def taps(self) -> list[tuple[str, Callable[[dict[str, Any]], None]]]:
        return [
            (topics.CAMERA_IMAGE, self.on_image),
            (topics.CAMERA_DEPTH, self.on_depth),
            (topics.CAMERA_INFO, self.on_camera_info),
            (topics.ODOM, self.on_odom),
        ]

    def on_camera_info(self, msg: dict[str, Any]) -> None:
        self._info = msg

    def on_image(self, msg: dict[str, Any]) -> None:
        self._pair(msg, self._images, self._depths, image_first=True)

    def on_depth(self, msg: dict[str, Any]) -> None:
        self._pair(msg, self._depths, self._images, image_first=False)

    def _pair(
        self,
        msg: dict[str, Any],
        mine: dict[float, dict[str, Any]],
        theirs: dict[float, dict[str, Any]],
        image_first: bool,
    ) -> None:
        stamp = stamp_seconds(msg)
        if stamp is None:  # it pairs with nothing: refused here, never queued
            self.bad_input += 1
            self.refusal = "a camera message with no header.stamp pairs with nothing"
            return
        other = theirs.pop(stamp, None)
        if other is None:
            mine[stamp] = msg
            while len(mine) > PAIRING:
                del mine[next(iter(mine))]
            return
        image, depth = (msg, other) if image_first else (other, msg)
        self._queue((_odom_pose(self._odom), image, depth, self._info))

    def _add(self, item: Any) -> None:
        odometry, image, depth, info = item
        frame = frame_of(image, depth, info, odometry, self.max_pixels)
        self.mapper.add(frame, colour_of(image, self.max_pixels))

    def _grid(self) -> tuple[Any, tuple[float, float]]:
        return self.mapper.grid()

    def _state(self) -> bytes:
        return self.mapper.state()

    def _resolution(self) -> float:
        return self.mapper.resolution

    def _path(self) -> list[tuple[float, float, float]]:
        return self.mapper.path

    def _stats(self) -> dict[str, Any]:
        behind = f"falling behind: {self.dropped} frames dropped" if self.dropped else ""
        return {**self.mapper.stats.__dict__, "pose": list(self.mapper.pose), "behind": behind}


def worker_for(session: MappingSession, prior: Any = None, resume: bytes = b"") -> SessionWorker:
    """The worker of ``session``'s kind (a visual map starts afresh: the camera's map is
    not matched against the grid it updates)."""
    if session.kind == MappingSession.VISUAL:
        return VisualWorker(session, resume)
    return LaserWorker(session, prior, resume)


def _odom_pose(msg: dict[str, Any] | None) -> tuple[float, float, float] | None:
    """The planar pose of a ``nav_msgs/Odometry`` in rosbridge JSON, or None."""
    found = pose_of(msg.get("pose")) if isinstance(msg, dict) else None  # type: ignore[arg-type]
    if found is None or not all(math.isfinite(v) for v in (found.x, found.y, found.yaw)):
        return None
    return found.x, found.y, found.yaw


Tell = Callable[[str, dict[str, Any]], None]
"""Publish a message on a topic as the server (``RosbridgeHub.tell``)."""


class MappingRunner:
    """The mapping workers of one server process (see the module's docstring)."""

    def __init__(self, hub: TopicTaps, tell: Tell | None = None) -> None:
        self.hub = hub
        self.tell = tell
        self.workers: dict[int, SessionWorker] = {}
        self._taps: dict[int, list[Tap]] = {}  # by session: the taps of its worker
        self._unmapped: dict[str, Tap] = {}  # robots here with no worker: their depth
        self._worker = TaskWorker("mapping runner", self._run)

    def start(self) -> None:
        self._worker.start()

    async def _run(self) -> None:
        while True:
            try:
                await self.sync()
            except UNREACHABLE as error:  # the database is away for a moment; try again
                REPORT.failed("mapping runner checks", error)
            except Exception:
                logger.exception("mapping runner: looking at sessions failed")
            await asyncio.sleep(POLL)

    async def sync(self) -> None:
        """Start workers for new running sessions of robots here; stop the others."""
        here = self.hub.robots()
        running = await sync_to_async(_running_sessions)(here)
        for pk, worker in list(self.workers.items()):
            if pk in running and worker.robot in here and not worker.stopped:
                continue
            del self.workers[pk]
            for tap in self._taps.pop(pk, []):
                tap.close()
            why = worker.why_stopped()
            await worker.stop(save=True)
            if worker.robot not in here:
                await sync_to_async(_interrupt)(pk, DISCONNECTED)
            elif why:
                await sync_to_async(_interrupt)(pk, STOPPED.format(why=why))
            self._told(worker.robot, pk, "stopped")
        for pk in running - self.workers.keys():
            found = await sync_to_async(_session_start)(pk)
            if found is not None:
                worker = worker_for(*found)
                worker.on_saved = lambda w=worker: self._told(w.robot, w.session_pk, "saved")
                self.workers[pk] = worker
                self._taps[pk] = [
                    self.hub.tap(topics.robot_topic(worker.robot, suffix), _message_to(callback))
                    for suffix, callback in worker.taps()
                ]
                worker.start()
                self._told(worker.robot, pk, "started")
        self._watch_unmapped(here)

    def _watch_unmapped(self, here: set[str]) -> None:
        """Tap the depth of the robots here with no worker: the first frame one sends is
        answered on its ``mapping`` topic (``NOT_MAPPING``), once until a session of it
        starts and ends; nothing of it is read or kept."""
        mapped = {worker.robot for worker in self.workers.values()}
        for robot in [r for r in self._unmapped if r not in here or r in mapped]:
            self._unmapped.pop(robot).close()
        for robot in here - mapped - self._unmapped.keys():
            depth = topics.robot_topic(robot, topics.CAMERA_DEPTH)
            self._unmapped[robot] = self.hub.tap(depth, self._not_mapping(robot))

    def _not_mapping(self, robot: str) -> OnMessage:
        """A tap's ``on_message`` that tells ``robot`` ``NOT_MAPPING`` the first time."""
        told: list[bool] = []

        def tell(_topic: Any, _msg: Any) -> None:
            if not told:
                told.append(True)
                self._tell(robot, MappingNews(None, "not_mapping", NOT_MAPPING))

        return tell

    def _told(self, robot: str, session: int, what: str) -> None:
        self._tell(robot, MappingNews(session, what))

    def _tell(self, robot: str, news: MappingNews) -> None:
        if self.tell is not None:
            self.tell(topics.robot_topic(robot, topics.MAPPING), dict(mapping_message(news)))


def _message_to(callback: Callable[[dict[str, Any]], None]) -> OnMessage:
    """A tap's ``on_message`` that hands ``callback`` the message alone."""
    return lambda _topic, msg: callback(msg)


def _running_sessions(robots: set[str]) -> set[int]:
    """Primary keys of the running sessions of ``robots``."""
    return set(sessions.open_session_of(robots).values_list("pk", flat=True))


def _session_start(pk: int) -> tuple[MappingSession, Any, bytes] | None:
    """A session with the grid it updates (or None) and the state to resume from (empty
    for a fresh one); None when it is no longer running."""
    from .. import services

    session = MappingSession.objects.select_related("robot", "submap").filter(pk=pk).first()
    if session is None or session.state != MappingSession.RUNNING:
        return None
    prior = None
    if session.submap is not None:
        submap = session.submap
        prior = (services.grid_of(submap), (submap.origin_x, submap.origin_y))
    return session, prior, bytes(session.keyframes)


NOT_MAPPING = (
    "camera frames are not mapped and nothing of them is kept: this robot has no running "
    "mapping session (an operator starts one: POST /api/mapping/sessions/ with kind visual)"
)
DISCONNECTED = "the robot disconnected: resume the session or discard it"
STOPPED = "mapping stopped on the server ({why}): resume the session or discard it"


def _interrupt(session_pk: int, reason: str) -> None:
    MappingSession.objects.filter(pk=session_pk, state=MappingSession.RUNNING).update(
        state=MappingSession.INTERRUPTED, reason=reason
    )
