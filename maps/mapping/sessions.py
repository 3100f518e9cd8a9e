"""Mapping sessions in the database: start, finish, resume, discard, publish; and what the
runner writes while a robot maps (``save_progress``).

A session is ``running`` while its robot maps, ``interrupted`` when the robot went away
(the map so far is kept: resume or discard it), ``finished`` when an operator ended it
(its map is a candidate sub-map), ``published`` once an admin made it a sub-map or a new
version of one, ``discarded`` otherwise. A robot has at most one open (running or
interrupted) session, which a database constraint guarantees.
"""

from __future__ import annotations

import math
from typing import Any, Protocol, cast

import numpy as np
from django.db import IntegrityError, transaction
from django.db.models import QuerySet

from cloudnav_core.grid import FREE_THRESH, OCCUPIED_THRESH

from .. import services, versions
from ..domain.mapfile import (
    LoadedMap,
    MapMetadata,
    export_map,
    load_map_upload,
    map_yaml_text,
)
from ..domain.versions import Reason
from ..domain.visual_mapping import stored_keyframes
from ..exceptions import KeyframeError, MappingError
from ..models import Building, MappingSession, SubMap, SubMapVersion
from ..visual import store
from . import maps3d

PATH_POINTS = 2000
"""Corrected poses kept for the page at most (the path is thinned evenly beyond)."""


class Whereabouts(Protocol):
    """Where a robot last said it was (``robots.models.RobotState``); None where unknown."""

    @property
    def x(self) -> float | None: ...

    @property
    def y(self) -> float | None: ...

    @property
    def yaw(self) -> float | None: ...


class SessionRobot(Protocol):
    """What a session asks of its robot (``robots.models.Robot``): its key, its name, and
    where it is while it is connected to a live server process (None while it is not)."""

    @property
    def pk(self) -> Any: ...

    @property
    def name(self) -> str: ...

    def online_state(self) -> Whereabouts | None: ...


def start(
    robot: SessionRobot,
    building: Building,
    code: str,
    by: Any = None,
    update: bool = False,
    kind: str = MappingSession.LASER,
) -> MappingSession:
    """Open a session for ``robot`` building sub-map ``code`` of ``building``: a new one,
    or (``update``) a new version of the existing one, made on its current version; of
    ``kind`` ``laser`` (scans) or ``visual`` (an RGB-D camera).

    Raises MappingError when the robot is offline or not registered here, already has an
    open session, or the code is taken (new) or unknown (update)."""
    if not building.robots.filter(pk=robot.pk).exists():
        raise MappingError(f"{robot.name} is not registered in {building.code}.")
    state = robot.online_state()
    if state is None:
        raise MappingError(f"{robot.name} is offline: start mapping once it is connected.")
    submap = building.submaps.defer("image").filter(code=code).first()
    if update and submap is None:
        raise MappingError(f"{building.code} has no sub-map {code} to update.")
    if not update and submap is not None:
        raise MappingError(f"{building.code}/{code} exists: update it, or choose a new code.")
    return _open(robot, building, code, submap, by, state, kind)


def _open(
    robot: SessionRobot,
    building: Building,
    code: str,
    submap: SubMap | None,
    by: Any,
    state: Whereabouts,
    kind: str,
) -> MappingSession:
    person = by if getattr(by, "is_authenticated", False) and by.pk else None
    pose = [v if v is not None and math.isfinite(v) else 0.0 for v in (state.x, state.y, state.yaw)]
    try:
        with transaction.atomic():
            return MappingSession.objects.create(
                # The robots.models.Robot it was given, a class maps below robots never imports.
                robot=cast(Any, robot),
                building=building,
                kind=kind,
                code=code,
                submap=submap,
                based_on=submap.revision if submap is not None else None,
                started_by=person,
                start_x=pose[0],
                start_y=pose[1],
                start_yaw=pose[2],
            )
    except IntegrityError:
        raise MappingError(
            f"{robot.name} already has a mapping session open: finish, resume or discard it."
        ) from None


def open_session_of(robot_names: set[str]) -> QuerySet[MappingSession]:
    """The running sessions of these robots (the runner's question)."""
    return MappingSession.objects.filter(robot__name__in=robot_names, state=MappingSession.RUNNING)


def change_state(
    session: MappingSession, to: str, allowed: tuple[str, ...], reason: str = ""
) -> MappingSession:
    """Move ``session`` to state ``to`` if it is in one of ``allowed``; raises MappingError."""
    with transaction.atomic():
        locked = MappingSession.objects.select_for_update().get(pk=session.pk)
        if locked.state not in allowed:
            raise MappingError(f"This session is {locked.state}: it cannot become {to}.")
        if to == MappingSession.RUNNING:
            clash = MappingSession.objects.filter(robot=locked.robot, state__in=MappingSession.OPEN)
            if clash.exclude(pk=locked.pk).exists():
                raise MappingError(f"{locked.robot.name} has another mapping session open.")
            if locked.robot.online_state() is None:
                raise MappingError(f"{locked.robot.name} is offline: resume once it is connected.")
        locked.state = to
        locked.reason = reason
        locked.save(update_fields=["state", "reason", "updated"])
        return locked


def save_progress(
    session_pk: int,
    grid: np.ndarray,
    origin: tuple[float, float],
    resolution: float,
    path: list[tuple[float, float, float]],
    stats: dict[str, Any],
    keyframes: bytes,
) -> None:
    """Write the map so far (as map_saver would: 0 / 205 / 254 PGM), the thinned path,
    the figures and the state to resume from. Only a running or finishing session is
    written: one discarded meanwhile stays as it is."""
    meta = _meta(resolution, origin)
    pgm, _ = export_map(grid, meta, meta.image)
    step = max(1, math.ceil(len(path) / PATH_POINTS))
    thinned = [[round(v, 3) for v in pose] for pose in path[::step]]
    MappingSession.objects.filter(
        pk=session_pk, state__in=[MappingSession.RUNNING, MappingSession.FINISHED]
    ).update(
        grid_pgm=pgm,
        origin_x=origin[0],
        origin_y=origin[1],
        resolution=resolution,
        path=thinned,
        stats=stats,
        keyframes=keyframes,
        snapshot=_next_snapshot(session_pk),
    )


def save_figures(session_pk: int, stats: dict[str, Any]) -> None:
    """Write the figures alone (before the first map: no keyframe yet), of a running or
    finishing session."""
    MappingSession.objects.filter(
        pk=session_pk, state__in=[MappingSession.RUNNING, MappingSession.FINISHED]
    ).update(stats=stats)


def _next_snapshot(session_pk: int) -> int:
    current = (
        MappingSession.objects.filter(pk=session_pk).values_list("snapshot", flat=True).first()
    )
    return (current or 0) + 1


def _meta(resolution: float, origin: tuple[float, float]) -> MapMetadata:
    return MapMetadata(
        image="map.pgm",
        resolution=resolution,
        origin=(origin[0], origin[1], 0.0),
        occupied_thresh=OCCUPIED_THRESH,
        free_thresh=FREE_THRESH,
        negate=False,
    )


def size_of(session: MappingSession) -> tuple[int, int]:
    """(width, height) in cells of the map so far, from its PGM header; (0, 0) before
    the first."""
    pgm = bytes(session.grid_pgm)
    if not pgm:
        return 0, 0
    width, height = pgm.split(b"\n")[1].split()[:2]
    return int(width), int(height)


def candidate(session: MappingSession) -> LoadedMap:
    """The session's map so far as a map_server pair. Raises MappingError before the
    first map was written."""
    if not session.grid_pgm:
        raise MappingError("No map yet: the robot has not sent scans to build one from.")
    meta = _meta(session.resolution, (session.origin_x, session.origin_y))
    name = f"{session.code}.pgm"
    meta = MapMetadata(**{**meta.__dict__, "image": name})
    return load_map_upload(map_yaml_text(meta).encode(), {name: bytes(session.grid_pgm)}, 10**8)


@transaction.atomic
def publish(session: MappingSession, by: Any = None, note: str = "") -> SubMapVersion:
    """Make a finished session's map a sub-map (a new one: version 1) or the next version
    of the one it updated. Raises MappingError for a session not finished, or
    VersionConflict when that sub-map moved past the version the session started on."""
    if session.state != MappingSession.FINISHED:
        raise MappingError(f"This session is {session.state}: finish it before publishing.")
    loaded = candidate(session)
    why = note or f"mapping session {session.pk} by {session.robot.name}"
    if session.submap is not None and session.based_on is not None:
        made = versions.publish(session.submap, loaded, Reason.MAPPING, session.based_on, by, why)
    else:
        if session.building.submaps.filter(code=session.code).exists():
            raise MappingError(
                f"{session.building.code}/{session.code} was made meanwhile: "
                "map it again as an update of it."
            )
        submap, _ = services.save_submap(
            session.building, session.code, loaded, author=by, note=why, reason=Reason.MAPPING
        )
        made = submap.versions.get(number=submap.revision)
    if session.kind == MappingSession.VISUAL:
        _register_keyframes(made.submap, session)
        maps3d.store(made, maps3d.view_of(session))
    change_state(session, MappingSession.PUBLISHED, (MappingSession.FINISHED,))
    return made


def _register_keyframes(submap: SubMap, session: MappingSession) -> int:
    """Make a visual session's keyframes ``submap``'s relocalisation map (replacing the
    keyframes it had: they belong to the map this version replaces); returns how many
    were stored (near-duplicates are dropped). Raises MappingError for a state that
    cannot be read."""
    try:
        keyframes = stored_keyframes(bytes(session.keyframes)) if session.keyframes else []
    except (ValueError, KeyframeError) as error:
        raise MappingError(f"The session's keyframes cannot be read: {error}") from None
    store.clear(submap)
    return sum(store.save(submap, session.robot.name, k) is not None for k in keyframes)
