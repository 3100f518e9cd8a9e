"""``/api/buildings/{code}/recording/``: what a building's robots record and how long it is
kept. Its members read it; its admins change it (``PUT`` whole or ``PATCH`` part). A
building that never chose has the defaults, stored at its first change."""

from __future__ import annotations

from typing import Any

from drf_spectacular.utils import extend_schema
from rest_framework import permissions, serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from cloudnav_core import topics
from maps.access import Role
from maps.models import Building
from maps.views.lookups import building_for
from telemetry.event_views import IsPerson
from telemetry.models import RecordingSettings

# Topics an admin may choose, relative to the robot; the camera is chosen by its rate.
RECORDABLE = sorted(topic for topic in topics.ROBOT_TOPIC_TYPES if not topic.startswith("camera/"))


class RecordingSettingsSerializer(serializers.ModelSerializer[RecordingSettings]):
    topics = serializers.ListField(
        child=serializers.ChoiceField(choices=RECORDABLE), allow_empty=True, max_length=50
    )

    class Meta:
        model = RecordingSettings
        fields = ["enabled", "topics", "camera_rate", "retention_days", "budget_mb"]

    def validate_topics(self, value: list[str]) -> list[str]:
        return sorted(set(value))

    def to_representation(self, instance: RecordingSettings) -> dict[str, Any]:
        return {**super().to_representation(instance), "recordable": RECORDABLE}


def settings_of(building: Building) -> RecordingSettings:
    """The building's settings, or the defaults (not stored) when it has none."""
    found = RecordingSettings.objects.filter(building=building).first()
    return found if found is not None else RecordingSettings(building=building)


class BuildingRecordingSettings(APIView):
    """What the building's robots record (``enabled``, ``topics``, ``camera_rate`` in
    frames per second, 0 = no camera) and what is kept (``retention_days``,
    ``budget_mb``), with the ``recordable`` topics. Members read; admins change."""

    permission_classes = [permissions.IsAuthenticated, IsPerson]

    @extend_schema(responses=RecordingSettingsSerializer)
    def get(self, request: Request, code: str) -> Response:
        building = building_for(request, code, Role.VIEWER)
        return Response(RecordingSettingsSerializer(settings_of(building)).data)

    @extend_schema(request=RecordingSettingsSerializer, responses=RecordingSettingsSerializer)
    def put(self, request: Request, code: str) -> Response:
        return self._change(request, code, partial=False)

    @extend_schema(request=RecordingSettingsSerializer, responses=RecordingSettingsSerializer)
    def patch(self, request: Request, code: str) -> Response:
        return self._change(request, code, partial=True)

    def _change(self, request: Request, code: str, partial: bool) -> Response:
        building = building_for(request, code, Role.ADMIN)
        serializer = RecordingSettingsSerializer(
            settings_of(building), data=request.data, partial=partial
        )
        serializer.is_valid(raise_exception=True)
        serializer.save(building=building)
        return Response(serializer.data)
