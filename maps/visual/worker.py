"""Keyframe ingestion off the request path: a bounded queue and one worker thread.

The request checks and decodes what it was sent (so bad input is refused at once and
nothing of it stored) and queues the pixels; the worker extracts the features, drops
near-duplicates and stores the rest. A full queue refuses at once (the robot tries
again with a later keyframe), so a flood of keyframes costs a bounded amount of memory
and never holds up anything else the server does: the rosbridge relay runs on the event
loop, this on its own thread, and OpenCV releases the GIL while it works.

The server starts the worker when it starts (``start_ingestion``, from
``cloudnav_web.background``); the vocabulary and the feature detector load with the first
keyframe, so a process that is sent none never loads them.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

from django.conf import settings
from django.db import close_old_connections

from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.workers import Inbox, Policy, Started, Worker
from maps.domain.keyframes import Depth, FeatureExtractor, Image
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError
from maps.models import SubMap
from maps.visual import store

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Job:
    submap_id: int
    robot: str
    image: Image
    depth: Depth
    pose: tuple[float, float, float]
    intrinsics: Intrinsics
    mount: Mount


@dataclass
class Counts:
    stored: int = 0
    duplicates: int = 0
    failed: int = 0
    refused: int = 0


class IngestQueue:
    """At most ``size`` keyframes waiting (a full inbox drops the newest: the robot tries
    again with a later keyframe); one named worker thread works through them."""

    def __init__(self, size: int) -> None:
        self._jobs: Inbox[Job] = Inbox("keyframes", size, Policy.DROP_NEWEST)
        self.worker = Worker("keyframes", self._work, wake=self._jobs.close)
        self.counts = Counts()

    def start(self) -> IngestQueue:
        """Start the worker (it waits for keyframes); return the queue."""
        self.worker.start()
        return self

    def submit(self, job: Job) -> bool:
        """Queue ``job``; False (nothing queued) when the queue is full."""
        if not self._jobs.put(job):
            self.counts.refused += 1
            return False
        return True

    def drain(self) -> None:
        """Return once every queued keyframe has been handled (for tests and commands)."""
        self._jobs.join()

    def _work(self, stopping: threading.Event) -> None:
        extractor: FeatureExtractor | None = None  # made with the first keyframe
        while not stopping.is_set() and (job := self._jobs.get()) is not None:
            try:
                extractor = extractor or FeatureExtractor(default_vocabulary())
                self._ingest(extractor, job)
            except Exception:  # the worker must outlive any one keyframe
                logger.exception("keyframe of %s failed", job.robot)
                self.counts.failed += 1
            finally:
                close_old_connections()
                self._jobs.done()

    def _ingest(self, extractor: FeatureExtractor, job: Job) -> None:
        submap = SubMap.objects.select_related("building").filter(pk=job.submap_id).first()
        if submap is None:
            return  # deleted while the keyframe waited
        try:
            features = extractor.keyframe(job.image, job.depth, job.pose, job.intrinsics, job.mount)
        except KeyframeError as error:
            logger.info("keyframe of %s dropped: %s", job.robot, error)
            self.counts.failed += 1
            return
        if store.save(submap, job.robot, features) is None:
            self.counts.duplicates += 1
        else:
            self.counts.stored += 1


_QUEUE: Started[IngestQueue] = Started("keyframe ingestion")


def start_ingestion() -> IngestQueue:
    """Make this process's queue (``CLOUDNAV_KEYFRAME_QUEUE`` long) and start its worker,
    once; return the queue."""
    return _QUEUE.start(lambda: IngestQueue(settings.CLOUDNAV_KEYFRAME_QUEUE).start())


def ingest_queue() -> IngestQueue:
    """This process's queue. Raises NotStarted before ``start_ingestion``."""
    return _QUEUE.get()
