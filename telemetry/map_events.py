"""Events of what the maps app did for robots and people (a bundle sent to a robot, a new
version of a sub-map), taken from its signals and written to the event log on commit; the
recorder of each robot's process reads them from there (``events.foreign_events``)."""

from __future__ import annotations

import time
from typing import Any

from django.db.models.signals import post_save

from maps.models import SubMap, SubMapVersion
from maps.signals import bundle_fetched
from telemetry.domain import events as derived

from .events import write_on_commit


def connect_signals() -> None:
    uid = "cloudnav-map-events"
    bundle_fetched.connect(_bundle_fetched, sender=SubMap, dispatch_uid=f"{uid}-bundle")
    post_save.connect(_version_saved, sender=SubMapVersion, dispatch_uid=f"{uid}-version")


def _bundle_fetched(sender: Any, submap: SubMap, robot: str, **_: Any) -> None:  # noqa: ARG001 (the signal's)
    building = submap.building.code
    draft = derived.bundle_fetched(robot, building, submap.map_id, submap.revision, time.time())
    write_on_commit(draft)


def _version_saved(sender: Any, instance: SubMapVersion, created: bool, **_: Any) -> None:  # noqa: ARG001
    if not created:
        return
    submap = instance.submap
    author = instance.author
    actor = f"user:{author.get_username()}" if author is not None else "server"
    draft = derived.map_version_changed(
        submap.building.code, submap.map_id, instance.number, instance.reason, actor, time.time()
    )
    write_on_commit(draft)
