"""Wire shapes of the robot registry."""

from __future__ import annotations

from typing import Any

from rest_framework import serializers

from maps.access import buildings_for
from maps.models import Building

from .models import Robot


class RobotSerializer(serializers.ModelSerializer[Robot]):
    buildings = serializers.SlugRelatedField(
        slug_field="code", queryset=Building.objects.all(), many=True, required=False
    )

    class Meta:
        model = Robot
        fields = ["name", "description", "buildings", "created", "token_rotated"]
        read_only_fields = ["created", "token_rotated"]

    def validate_buildings(self, value: list[Building]) -> list[Building]:
        """An admin may register robots only for buildings they administer."""
        allowed = set(buildings_for(self.context["request"].user))
        foreign = [b.code for b in value if b not in allowed]
        if foreign:
            raise serializers.ValidationError(f"You do not administer {', '.join(foreign)}.")
        return value


class RobotCreatedSerializer(RobotSerializer):
    """The answer to a registration: the only time the token is shown."""

    token = serializers.CharField(read_only=True)

    class Meta(RobotSerializer.Meta):
        fields = [*RobotSerializer.Meta.fields, "token"]


class TokenSerializer(serializers.Serializer[Any]):
    name = serializers.CharField(read_only=True)
    token = serializers.CharField(read_only=True)
