"""``GET /api/robots/{name}/recording.mcap`` and ``/api/buildings/{code}/recording.mcap``
(and ``recording.bag``, a ROS 1 bag written by ``rosbags``).

``start`` and ``end`` are ISO 8601 times (a time without zone is UTC) or Unix seconds;
``end`` defaults to now and ``start`` to an hour before ``end``. The answer is one MCAP
file (ROS 1 profile) streamed as it is written; a range without data is a valid, empty
file. Robots and buildings the requester may not see answer 404, as if absent.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Any

from django.http import Http404, StreamingHttpResponse
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from cloudnav_django.heavy import budgeted_stream, client_of, export_budget
from maps.access import buildings_for, robot_of
from robots.models import Robot

from . import export
from .files import Record
from .service import flush_recordings, recording_config

NS = 1_000_000_000
DEFAULT_SPAN = 3600


def parse_time(raw: str) -> int:
    """Nanoseconds since the epoch of ISO 8601 text or Unix seconds. Raises ValueError."""
    text = raw.strip()
    try:
        return int(float(text) * NS)
    except ValueError:
        pass
    moment = datetime.fromisoformat(text.replace("Z", "+00:00"))
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return int(moment.timestamp() * NS)


def time_range(params: Any) -> tuple[int, int]:
    """``(start_ns, end_ns)`` of the query. Raises ValidationError naming the field."""
    errors: dict[str, str] = {}
    values: dict[str, int] = {}
    for name in ("start", "end"):
        raw = params.get(name)
        if raw:
            try:
                values[name] = parse_time(raw)
            except (ValueError, OverflowError):
                errors[name] = "Give an ISO 8601 time or Unix seconds."
    if errors:
        raise serializers.ValidationError(errors)
    end = values.get("end", time.time_ns())
    start = values.get("start", end - DEFAULT_SPAN * NS)
    if start > end:
        raise serializers.ValidationError({"start": "start is after end."})
    return start, end


def recording_response(
    request: Request, robots: list[str], start: int, end: int, name: str, kind: str
) -> StreamingHttpResponse:
    """The robots' recording in ``[start, end]`` as ``kind`` (``mcap`` or ``bag``), within
    the export budget: Overloaded (429) past the requester's share, (503) the process's."""
    ticket = export_budget().take(client_of(request), export.EXPORT_MEMORY_BYTES)
    people = robot_of(request.user) is None
    try:
        content, content_type = _export(robots, start, end, kind, people)
    except BaseException:
        ticket.release()
        raise
    response = budgeted_stream(request, ticket, content, content_type)
    filename = f"{name}-{start // NS}-{end // NS}.{kind}"
    response["Content-Disposition"] = f'attachment; filename="{filename}"'
    response["Cache-Control"] = "no-store"
    return response


def _export(
    robots: list[str], start: int, end: int, kind: str, people: bool
) -> tuple[Iterator[bytes], str]:
    """The file's pieces, to be made as they are sent, and its content type; the events
    topic only for ``people`` (a robot learns no one's name from it)."""
    flush_recordings(robots)
    taken = export.snapshot(recording_config().root, robots, start, end)

    def source() -> Iterator[Record]:
        found = export.snapshot_records(taken, start, end)
        return found if people else export.without_events(found)

    if kind == "bag":
        return export.bag_stream(source), "application/x-rosbag"
    return export.mcap_stream(source()), "application/mcap"


RANGE = [
    OpenApiParameter("start", str, description="ISO 8601 or Unix seconds (default: end - 1 h)"),
    OpenApiParameter("end", str, description="ISO 8601 or Unix seconds (default: now)"),
]


class RobotRecording(APIView):
    """One robot's recording between ``start`` and ``end`` as one MCAP file (or bag)."""

    kind = "mcap"

    @extend_schema(parameters=RANGE, responses={(200, "application/mcap"): OpenApiTypes.BINARY})
    def get(self, request: Request, name: str) -> StreamingHttpResponse:
        start, end = time_range(request.query_params)
        visible_robot(request, name)
        return recording_response(request, [name], start, end, name, self.kind)


REPLAY_LIMIT = 5000


def visible_robot(request: Request, name: str) -> None:
    """Raise Http404 unless the requester may read robot ``name``'s recording: a person of
    one of its buildings, or the robot itself (another robot's is none of its business)."""
    robot = robot_of(request.user)
    if robot is not None and robot.name != name:
        raise Http404("No such robot.")
    visible = Robot.objects.filter(name=name, buildings__in=buildings_for(request.user))
    if not visible.exists():
        raise Http404("No such robot.")


class RobotReplay(APIView):
    """A window of a robot's recording as rosbridge JSON for the robot page's replay:
    ``{"span": [first, last] | null, "messages": [{"t", "topic", "msg"}], "more", "next"}``
    (times in Unix seconds); ``topics`` (comma separated, relative to the robot) narrows
    it, and at most ``limit`` messages come back (``next`` is where to ask again)."""

    @extend_schema(
        parameters=[
            *RANGE,
            OpenApiParameter("topics", str, description="e.g. pose,scan,plan"),
            OpenApiParameter("limit", int, description=f"at most {REPLAY_LIMIT}"),
        ],
        responses={200: OpenApiTypes.OBJECT},
    )
    def get(self, request: Request, name: str) -> Response:
        start, end = time_range(request.query_params)
        visible_robot(request, name)
        raw_topics = request.query_params.get("topics")
        topics = {t.strip() for t in raw_topics.split(",") if t.strip()} if raw_topics else None
        try:
            limit = min(max(int(request.query_params.get("limit", REPLAY_LIMIT)), 1), REPLAY_LIMIT)
        except ValueError:
            raise serializers.ValidationError({"limit": "Give a whole number."}) from None
        root = recording_config().root
        flush_recordings([name])
        found = export.records(root, [name], start, end)
        if robot_of(request.user) is not None:
            found = export.without_events(found)
        window = export.json_window(found, topics, limit)
        return Response({"span": export.span(root, name), **window})


class BuildingRecording(APIView):
    """Every robot of a building between ``start`` and ``end`` as one MCAP file (or bag)."""

    kind = "mcap"

    @extend_schema(parameters=RANGE, responses={(200, "application/mcap"): OpenApiTypes.BINARY})
    def get(self, request: Request, code: str) -> StreamingHttpResponse:
        start, end = time_range(request.query_params)
        building = buildings_for(request.user).filter(code=code).first()
        if building is None or robot_of(request.user) is not None:  # robots: their own only
            raise Http404("No such building.")
        robots = list(building.robots.values_list("name", flat=True))
        return recording_response(request, robots, start, end, code, self.kind)
