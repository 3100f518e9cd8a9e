"""Wire shapes of the robot registry.

A robot may be registered for buildings of several tenants. Each admin sees, names and
changes only the links to buildings they administer: a form lists those alone, an answer
shows no other building's code, and an update keeps the links to the others as they are.
"""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from rest_framework import serializers

from cloudnav_core.topics import GLOBAL_NAMESPACES
from maps.access import Role, buildings_for, buildings_where, global_role
from maps.models import Building

from .models import Robot, ros_name_validator

# One answer for every name that cannot be had: a robot's (of any tenant) or a namespace
# the server keeps for itself, so a refusal confirms no other tenant's robot.
NAME_UNAVAILABLE = "This name is not available: choose another."


def administered(user: Any) -> QuerySet[Building]:
    """The buildings ``user`` administers (all of them for a superuser)."""
    if user is None or global_role(user) < Role.ADMIN:
        return Building.objects.none()
    return buildings_where(user, Role.ADMIN)


class AdministeredBuilding(serializers.SlugRelatedField[Building]):
    """A building code, among the buildings the requester administers only: a browsable
    form lists nothing else, and any other code reads as one that does not exist."""

    def get_queryset(self) -> QuerySet[Building]:
        request = self.context.get("request")
        return administered(getattr(request, "user", None))


class RobotSerializer(serializers.ModelSerializer[Robot]):
    buildings = AdministeredBuilding(slug_field="code", many=True, required=False)

    class Meta:
        model = Robot
        fields = ["name", "description", "buildings", "created", "token_rotated"]
        read_only_fields = ["created", "token_rotated"]
        # the name's uniqueness is checked by validate_name, whose answer names no robot
        extra_kwargs = {"name": {"validators": [ros_name_validator]}}

    def validate_name(self, name: str) -> str:
        """The name, unless a robot has it (of any building) or the server keeps it."""
        others = Robot.objects.filter(name=name)
        if self.instance is not None:
            others = others.exclude(pk=self.instance.pk)
        if name in GLOBAL_NAMESPACES or others.exists():
            raise serializers.ValidationError(NAME_UNAVAILABLE)
        return name

    def to_representation(self, instance: Robot) -> dict[str, Any]:
        data = super().to_representation(instance)
        visible = self._visible_codes()
        if visible is not None:
            data["buildings"] = [code for code in data["buildings"] if code in visible]
        return data

    def _visible_codes(self) -> set[str] | None:
        """Codes of the buildings the requester sees; None for all (a superuser)."""
        request = self.context.get("request")
        user = getattr(request, "user", None)
        if user is None or user.is_superuser:
            return None
        if self._visible is None:
            self._visible = set(buildings_for(user).values_list("code", flat=True))
        return self._visible

    _visible: set[str] | None = None

    def update(self, instance: Robot, validated_data: dict[str, Any]) -> Robot:
        """Update; the new ``buildings`` replace the requester's own links only."""
        buildings = validated_data.pop("buildings", None)
        robot = super().update(instance, validated_data)
        if buildings is not None:
            mine = set(administered(self.context["request"].user))
            kept = [b for b in robot.buildings.all() if b not in mine]
            robot.buildings.set([*kept, *buildings])
        return robot


class RobotCreatedSerializer(RobotSerializer):
    """The answer to a registration: the only time the token is shown."""

    token = serializers.CharField(read_only=True)

    class Meta(RobotSerializer.Meta):
        fields = [*RobotSerializer.Meta.fields, "token"]


class TokenSerializer(serializers.Serializer[Any]):
    name = serializers.CharField(read_only=True)
    token = serializers.CharField(read_only=True)
