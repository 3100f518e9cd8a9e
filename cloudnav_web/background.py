"""Every background worker of the server process, started from here and nowhere else.

Each worker is a ``cloudnav_core.workers`` worker: it registers with ``REGISTRY`` when it
starts, and ``cloudnav_web.shutdown`` stops and joins them all on SIGTERM (the registry
does at exit elsewhere). ``install`` runs once, when the ASGI application is made
(``cloudnav_web.asgi``):

- it starts the workers that serve requests (``start_serving``): keyframe ingestion
  (``maps.visual.worker``), the relocalisation lanes (``maps.visual.lanes``) and the video
  encoders (``telemetry.video.relay``). They wait idle; what they work with (OpenCV's
  detector, the vocabulary, a building's keyframes) loads with the first request that
  needs it, so start-up stays quick (measured: docs/design.md, "Background work"). Asked
  for before they are started, they raise ``NotStarted``; tests that serve requests
  without the ASGI application call ``start_serving`` as the server does
  (``tests/conftest.py``).
- it has each hub (one per event loop, ``telemetry.rosbridge.hub.get_hub``, started by the
  first connection or video request) start, once it has started, the workers that tap its
  topics (``start_with_hub``): the recorder (``telemetry.recording``, one per process, if
  recording is on), the mapping runner and its sessions (``maps.mapping.runner``) and map
  upkeep (``maps.mapping.upkeep``); their thread pools are made as their modules load,
  imported here.

``tests/test_workers_started_in_one_place.py`` fails when a worker is made or started
anywhere else.
"""

from __future__ import annotations

from maps.mapping.runner import MappingRunner
from maps.mapping.upkeep import UpkeepRunner
from maps.visual.lanes import start_relocalisation
from maps.visual.worker import start_ingestion
from telemetry.recording.service import start_recorder
from telemetry.rosbridge.hub import Hub, on_hub_start
from telemetry.video.relay import start_encoders


def install() -> None:
    start_serving()
    on_hub_start(start_with_hub)


def start_serving() -> None:
    """Start the workers that serve requests (once; they wait for the first)."""
    start_ingestion()  # keyframes robots send, stored off the request path
    start_relocalisation()  # relocalisation calls, REST and rosbridge alike
    start_encoders()  # video streams' encoding threads


def start_with_hub(hub: Hub) -> None:
    recorder = start_recorder()  # the process's, whichever hub starts first
    if recorder is not None:
        hub.record_with(recorder)  # every topic of the robots connected here, to files
    MappingRunner(hub, tell=hub.tell).start()  # mapping sessions of the robots connected here
    UpkeepRunner(hub).start()  # laser evidence about the stored maps, from the same robots
