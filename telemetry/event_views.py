"""``/api/events/``: the fleet's events, filtered; acknowledging alerts; the open-alert count.

People see the events of the buildings they are members of; operators and admins
acknowledge alerts there. Robots read no events.
"""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from django.utils import timezone
from django.utils.dateparse import parse_datetime
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import generics, permissions, serializers
from rest_framework.exceptions import NotFound, PermissionDenied, ValidationError
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView
from typing_extensions import override

from maps.access import Role, buildings_for, global_role, role_in

from .models import Event

MAX_EVENTS = 1000
# Query parameter -> the field it filters.
FILTERS = {
    "building": "building__code",
    "robot": "robot__name",
    "kind": "kind",
    "severity": "severity",
}


class EventSerializer(serializers.ModelSerializer[Event]):
    building = serializers.CharField(source="building.code", default=None, read_only=True)
    robot = serializers.CharField(source="robot.name", default=None, read_only=True)
    acknowledged_by = serializers.CharField(
        source="acknowledged_by.username", default=None, read_only=True
    )

    class Meta:
        model = Event
        fields = [
            "id", "time", "building", "robot", "kind", "severity", "actor", "message", "data",
            "alert", "acknowledged_at", "acknowledged_by", "cleared_at",
        ]  # fmt: skip
        read_only_fields = fields


class IsPerson(permissions.BasePermission):
    message = "Only people with a role read events."

    @override
    def has_permission(self, request: Request, view: Any) -> bool:
        return global_role(request.user) >= Role.VIEWER


def visible_events(user: Any) -> QuerySet[Event]:
    return Event.objects.filter(building__in=buildings_for(user)).select_related(
        "building", "robot", "acknowledged_by"
    )


def open_alerts(events: QuerySet[Event]) -> QuerySet[Event]:
    """Alerts nobody acknowledged whose condition has not ended."""
    return events.filter(alert=True, acknowledged_at__isnull=True, cleared_at__isnull=True)


def _text(params: Any, key: str) -> str:
    """The filter ``key`` ("" if absent); ValidationError for a NUL, which no stored text
    holds (and PostgreSQL refuses)."""
    text = str(params.get(key) or "")
    if "\x00" in text:
        raise ValidationError({key: ["no NUL characters"]})
    return text


def _time(params: Any, key: str) -> Any:
    text = _text(params, key)
    if not text:
        return None
    try:
        when = parse_datetime(text)
    except ValueError:  # well formed but no such moment (2026-02-30)
        when = None
    if when is None:
        raise ValidationError({key: ["an ISO 8601 date and time"]})
    return when


@extend_schema(
    parameters=[
        OpenApiParameter("building", str),
        OpenApiParameter("robot", str),
        OpenApiParameter("kind", str),
        OpenApiParameter("severity", str),
        OpenApiParameter("alerts", str, enum=["open", "all"]),
        OpenApiParameter("since", str),
        OpenApiParameter("until", str),
        OpenApiParameter("limit", int),
    ]
)
class EventList(generics.ListAPIView[Event]):
    """Events, newest first: filter by building, robot, kind, severity, time (``since``,
    ``until``, ISO 8601); ``alerts=open`` gives the alerts nobody acknowledged yet whose
    condition has not ended (``cleared_at``),
    ``alerts=all`` every alert; ``limit`` (default 100, at most 1000)."""

    serializer_class = EventSerializer
    permission_classes = [permissions.IsAuthenticated, IsPerson]
    pagination_class = None

    def get_queryset(self) -> QuerySet[Event]:
        params = self.request.query_params
        events = visible_events(self.request.user)
        for key, field in FILTERS.items():
            if value := _text(params, key):
                events = events.filter(**{field: value})
        if params.get("alerts") == "all":
            events = events.filter(alert=True)
        elif params.get("alerts") == "open":
            events = open_alerts(events)
        if (since := _time(params, "since")) is not None:
            events = events.filter(time__gte=since)
        if (until := _time(params, "until")) is not None:
            events = events.filter(time__lt=until)
        return events[: self._limit(params)]

    @staticmethod
    def _limit(params: Any) -> int:
        try:
            limit = int(params.get("limit", 100))
        except ValueError:
            raise ValidationError({"limit": ["a whole number"]}) from None
        return max(1, min(limit, MAX_EVENTS))


class Acknowledge(APIView):
    """``POST``: acknowledge an alert (operators and admins of its building)."""

    permission_classes = [permissions.IsAuthenticated, IsPerson]

    @extend_schema(request=None, responses=EventSerializer)
    def post(self, request: Request, pk: int) -> Response:
        event = visible_events(request.user).filter(pk=pk, alert=True).first()
        if event is None or event.building is None:
            raise NotFound("No such alert.")
        if role_in(request.user, event.building) < Role.OPERATOR:
            raise PermissionDenied("Only operators and admins acknowledge alerts.")
        if event.acknowledged_at is None:
            event.acknowledged_at = timezone.now()
            event.acknowledged_by = request.user  # type: ignore[assignment]
            event.save(update_fields=["acknowledged_at", "acknowledged_by"])
        return Response(EventSerializer(event).data)


class OpenAlerts(APIView):
    """``GET``: how many alerts wait for acknowledgement in the requester's buildings."""

    permission_classes = [permissions.IsAuthenticated, IsPerson]

    @extend_schema(responses=serializers.DictField(child=serializers.IntegerField()))
    def get(self, request: Request) -> Response:
        """With an ETag of the count: a page asking again gets 304 while it is unchanged
        (an unchanged check, kept out of the INFO log)."""
        count = open_alerts(visible_events(request.user)).count()
        etag = f'"open-{count}"'
        headers = {"ETag": etag, "Cache-Control": "private, no-cache"}
        if etag in request.headers.get("If-None-Match", ""):
            return Response(status=304, headers=headers)
        return Response({"open": count}, headers=headers)
