"""The recorder of one server process: it taps the topic bus and writes MCAP off the loop.

The tap (``Recorder.offered``, given to ``hub.tap(EVERY_TOPIC, ...)``) runs on the relay
loop for every message the bus fans out, local or from another process, and does three
dictionary look-ups and one append: is the topic a robot's, is that robot connected to
this process (so in scaled mode each robot is recorded once, by the process it is
connected to), does its plan record this topic (and is a camera frame due). The message
goes into that robot's bounded inbox, which drops the newest (``Policy.DROP_NEWEST``):
when it is full the message is counted in ``dropped`` and left, so the relay never waits.
One named writer thread (a registered ``Worker``) drains the inboxes,
serialises to ROS 1, writes the robot's rotating files, refreshes the plans from the
database and applies each building's retention. Events come two ways: those this
process's event log derives through ``Recorder.event`` at once, the others (another
process's, a request's) from the event log every ``events_seconds``.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from django.conf import settings

from cloudnav_core import topics
from cloudnav_core.workers import Inbox, Policy, Worker
from telemetry.domain import names, ros1
from telemetry.domain.bus import Topic
from telemetry.domain.events import EVENT_TYPE, EVENTS_TOPIC, EventDraft, as_log
from telemetry.models import CAMERA_TOPIC
from telemetry.rosbridge.config import setting

from . import files
from .plans import Plan, Retention

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecorderConfig:
    root: Path
    queue_size: int = 4096
    file_seconds: float = 3600.0
    file_bytes: int = 256 * 2**20
    plan_seconds: float = 30.0
    retention_seconds: float = 60.0
    poll_seconds: float = 0.05
    events_seconds: float = 1.0

    @classmethod
    def load(cls) -> RecorderConfig:
        """The configuration from settings or the environment."""
        default_root = Path(settings.BASE_DIR) / "var" / "recordings"
        return cls(
            root=Path(setting("CLOUDNAV_RECORDING_DIR", default_root, Path)),
            queue_size=setting("CLOUDNAV_RECORDING_QUEUE", 4096, int),
            file_seconds=setting("CLOUDNAV_RECORDING_FILE_SECONDS", 3600.0, float),
            file_bytes=setting("CLOUDNAV_RECORDING_FILE_BYTES", 256 * 2**20, int),
        )


def env_flag(raw: str) -> bool:
    return raw.strip().lower() not in {"0", "false", "no", "off"}


def recording_on() -> bool:
    """Whether this server records (``CLOUDNAV_RECORDING``); exports work either way."""
    return bool(setting("CLOUDNAV_RECORDING", True, env_flag))


Queued = tuple[str, str, Mapping[str, Any], int]
"""A message waiting for the writer: topic, type, the message, its log time (ns)."""


@dataclass
class RobotQueue:
    """One robot's messages waiting for the writer, and what it had to drop."""

    queue: Inbox[Queued]
    plan: Plan | None = None
    last_camera: float = 0.0
    lost: int = 0  # written to a full disk
    written: int = 0
    failed: int = 0

    @property
    def dropped(self) -> int:
        """Messages not recorded: the inbox's (full) and the disk's (full)."""
        return self.queue.dropped + self.lost


# the robots -> each one's plan (``plans.plans_for``: one round of queries for them all)
PlanSource = Callable[[list[str]], Mapping[str, Plan]]
RetentionSource = Callable[[], Iterable[Retention]]
# (last event id read or None at first, the robots recorded here) -> (last id, events):
# the events of the log this process's event log did not derive (``foreign_events``)
EventSource = Callable[[int | None, frozenset[str]], tuple[int, list[EventDraft]]]


class Recorder:
    """Records the robots connected to this process (see the module's docstring)."""

    def __init__(
        self,
        config: RecorderConfig,
        plans: PlanSource,
        retentions: RetentionSource,
        clock: Callable[[], float] = time.time,
        foreign_events: EventSource | None = None,
    ) -> None:
        self.config = config
        self.plans = plans
        self.retentions = retentions
        self.clock = clock
        self.foreign_events = foreign_events
        self._events_after: int | None = None
        self._events_at = 0.0
        self.robots: dict[str, RobotQueue] = {}
        self._writers: dict[str, files.RotatingFiles] = {}
        self._worker = Worker("recorder", self._run)
        self._plans_at = 0.0
        self._retention_at = 0.0
        self._leaving: deque[RobotQueue] = deque()
        self._arrived: deque[str] = deque()  # robots whose files to repair
        # flush requests: the robots whose files to flush, and what to set when done
        self._flushes: deque[tuple[frozenset[str], threading.Event]] = deque()

    # ------------------------------------------------------------ on the relay loop

    def connected(self, robot: str) -> None:
        """Record ``robot``, which arrived here; what a process it was recorded by before
        left unfinished (killed) is repaired now, not at the next retention pass."""
        if robot not in self.robots:
            queue: Inbox[Queued] = Inbox(robot, self.config.queue_size, Policy.DROP_NEWEST)
            self.robots[robot] = RobotQueue(queue)
            self._arrived.append(robot)

    def disconnected(self, robot: str) -> None:
        """Stop taking the robot's messages; what is queued is still written."""
        entry = self.robots.pop(robot, None)
        if entry is not None and entry.queue:
            self._leaving.append(entry)

    def offered(self, topic: Topic, msg: Mapping[str, Any]) -> None:
        """The bus's tap: queue ``msg`` if its robot is here and its plan records it."""
        name = topic.name
        robot, _, suffix = name[1:].partition("/")
        entry = self.robots.get(robot)
        if entry is None or not suffix:
            return
        plan = entry.plan
        if plan is not None and suffix not in plan.topics:
            return
        now = self.clock()
        if suffix == CAMERA_TOPIC:
            if plan is None or now - entry.last_camera < plan.camera_interval:
                return
            entry.last_camera = now
        type_name = topic.type or topics.ROBOT_TOPIC_TYPES.get(suffix, "")
        entry.queue.put((name, type_name, msg, int(now * 1e9)))

    def event(self, draft: EventDraft) -> None:
        """An event the server derived: queued on its robot's ``/{robot}/events`` channel
        (``rosgraph_msgs/Log``) when that robot is recorded here, stamped with its time;
        a full queue counts it in ``dropped`` as any message."""
        entry = self.robots.get(draft.robot or "")
        if entry is None or (entry.plan is not None and not entry.plan.topics):
            return
        topic = topics.robot_topic(draft.robot or "", EVENTS_TOPIC)
        entry.queue.put((topic, EVENT_TYPE, as_log(draft), int(draft.time * 1e9)))

    def stats(self) -> dict[str, dict[str, int]]:
        return {
            robot: {"queued": len(e.queue), "dropped": e.dropped, "written": e.written}
            for robot, e in list(self.robots.items())
        }

    def flush(self, robots: Iterable[str], timeout: float = 5.0) -> bool:
        """Have the writer write every message of ``robots`` queued before this call and
        end their files' open chunks, so reading the files now gives everything recorded
        up to now (an export). Waits at most ``timeout`` seconds; False when the writer
        did not answer in time (or is not running)."""
        if not self._worker.alive:
            return False
        done = threading.Event()
        self._flushes.append((frozenset(robots), done))
        return done.wait(timeout)

    # ------------------------------------------------------------ the writer thread

    def start(self) -> None:
        self._worker.start()

    def stop(self, timeout: float = 10.0) -> None:
        """Write what is queued, finish every file and stop the thread."""
        self._worker.stop()
        self._worker.join(timeout)

    def _run(self, stopping: threading.Event) -> None:
        self._guarded(self._repair)
        while not stopping.is_set():
            self._guarded(self.step)
            stopping.wait(self.config.poll_seconds)
        self._guarded(self.step)
        for writer in self._writers.values():
            self._guarded(writer.close)
        self._writers.clear()

    def _guarded(self, work: Callable[[], object]) -> None:
        """Run ``work``; a failure is logged, never the end of recording (or the server)."""
        try:
            work()
        except Exception:
            log.exception("recorder: %s failed", getattr(work, "__name__", work))

    def _repair(self) -> None:
        files.repair_all(self.config.root)

    def step(self) -> None:
        """One pass of the writer: plans when due, every queue drained, retention when due."""
        now = time.monotonic()
        flushes = [self._flushes.popleft() for _ in range(len(self._flushes))]
        if now - self._plans_at >= self.config.plan_seconds:
            self._refresh_plans(list(self.robots))
            self._plans_at = now
        elif unplanned := [r for r, e in list(self.robots.items()) if e.plan is None]:
            self._refresh_plans(unplanned)  # robots that just arrived
        if self.foreign_events is not None and now - self._events_at >= self.config.events_seconds:
            self._events_at = now
            self._guarded(self._read_foreign_events)
        while self._leaving:
            self._drain(self._leaving.popleft())
        while self._arrived:
            robot = self._arrived.popleft()
            self._guarded(functools.partial(files.repair_robot, self.config.root, robot))
        self._close_idle()
        for robot, entry in list(self.robots.items()):
            self._drain(entry, robot=robot)
        for robots, done in flushes:
            self._flush(robots)
            done.set()
        if now - self._retention_at >= self.config.retention_seconds:
            self._retention_at = now
            self._guarded(self._apply_retention)

    def _read_foreign_events(self) -> None:
        """Queue the events other processes and requests derived for the robots here
        (a goal sent from another process, a bundle fetched, a new map version)."""
        assert self.foreign_events is not None
        self._events_after, drafts = self.foreign_events(self._events_after, frozenset(self.robots))
        for draft in drafts:
            self.event(draft)

    def _flush(self, robots: frozenset[str]) -> None:
        for robot in robots:
            writer = self._writers.get(robot)
            if writer is not None:
                self._guarded(writer.flush)

    def _refresh_plans(self, robots: list[str]) -> None:
        try:
            plans = self.plans(robots)
        except Exception:
            log.exception("recorder: no plans for %d robots", len(robots))
            return
        for robot, plan in plans.items():
            entry = self.robots.get(robot)
            if entry is not None:
                entry.plan = plan

    def _close_idle(self) -> None:
        """Finish the files of robots that left."""
        for robot in [r for r in self._writers if r not in self.robots]:
            self._guarded(self._writers.pop(robot).close)

    def _drain(self, entry: RobotQueue, robot: str | None = None) -> None:
        plan = entry.plan
        for topic, type_name, msg, log_time in entry.queue.take_all():
            robot = robot or names.first_segment(topic)
            suffix = topic[len(robot) + 2 :]
            if plan is not None and not recorded(plan, suffix):
                continue
            self._write(entry, robot, topic, type_name, msg, log_time)

    def _write(
        self,
        entry: RobotQueue,
        robot: str,
        topic: str,
        type_name: str,
        msg: Mapping[str, Any],
        log_time: int,
    ) -> None:
        described = ros1.described(type_name) if type_name else None
        if described is None:
            entry.failed += 1
            return
        try:
            data = ros1.encode(type_name, msg)
        except ros1.Ros1EncodeError:
            entry.failed += 1
            return
        record = files.Record(topic, described[0], described[1], log_time, data)
        writer = self._writers.get(robot)
        if writer is None:
            writer = self._writers[robot] = files.RotatingFiles(
                self.config.root, robot, self.config.file_seconds, self.config.file_bytes
            )
        try:
            writer.write(record)
            entry.written += 1
        except OSError:
            # a full disk: make room from this robot's oldest files and carry on
            entry.lost += 1
            self._guarded(writer.close)
            self._writers.pop(robot, None)
            self._guarded(lambda: self._free_space(robot))

    def _free_space(self, robot: str) -> None:
        for f in files.files_of(self.config.root, robot)[:-1]:  # the newest is the one cut
            if files.delete_if_closed(f.path):
                return

    def _apply_retention(self) -> None:
        """Prune each building's files, and repair what a process that died meanwhile left
        (in the scaled mode its robots are recorded again by their new process)."""
        for retention in self.retentions():
            prune(self.config.root, retention, self.clock())
        self._repair()


def recorded(plan: Plan, suffix: str) -> bool:
    """Whether ``plan`` records the robot's topic ``suffix``: its events whenever it
    records anything."""
    return suffix in plan.topics or (suffix == EVENTS_TOPIC and bool(plan.topics))


def prune(root: Path, retention: Retention, now: float) -> list[Path]:
    """Delete the building's files older than its days, then its oldest files until its
    robots hold at most its budget; only closed files go, never one a writer of any
    process holds (``files.delete_if_closed``). Returns what went."""
    oldest_kept = int((now - retention.days * 86400) * 1e9)
    candidates: list[files.RecordingFile] = []
    for robot in retention.robots:
        candidates.extend(files.files_of(root, robot))
    candidates.sort()
    gone = []
    total = sum(f.size for f in candidates)
    for f in candidates:
        too_old = f.last_ns < oldest_kept
        if not (too_old or total > retention.budget):
            continue
        size = f.size
        if files.delete_if_closed(f.path):
            total -= size
            gone.append(f.path)
    return gone
