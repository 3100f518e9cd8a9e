"""Every background worker of the server process, started from one place.

Each worker is a ``cloudnav_core.workers`` worker: it registers with ``REGISTRY`` when it
starts, and ``cloudnav_web.shutdown`` stops and joins them all on SIGTERM (the registry
does at exit elsewhere). ``install`` (from the ASGI application, ``cloudnav_web.asgi``)
has each hub (one per event loop, ``telemetry.rosbridge.hub.get_hub``) start, once it has started,
the workers that tap its topics: the mapping runner (``maps.mapping.runner``, SLAM
sessions) and map upkeep (``maps.mapping.upkeep``); the recorder starts with the hub it
taps (``Hub.start``). The workers serving requests start with the first request that
needs them, so a process that never gets one never loads what they need: keyframe
ingestion (``maps.visual.worker``), relocalisation (``maps.visual.lanes``) and the video
encoders (``telemetry.video.relay``).
"""

from __future__ import annotations

from maps.mapping.runner import MappingRunner
from maps.mapping.upkeep import UpkeepRunner
from telemetry.rosbridge.hub import Hub, on_hub_start


def install() -> None:
    on_hub_start(start_with_hub)


def start_with_hub(hub: Hub) -> None:
    MappingRunner(hub, tell=hub.tell).start()  # mapping sessions of the robots connected here
    UpkeepRunner(hub).start()  # laser evidence about the stored maps, from the same robots
