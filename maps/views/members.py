"""A building's members and their roles, kept so that a building never loses its last admin."""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from rest_framework import generics
from rest_framework.exceptions import NotFound, PermissionDenied, ValidationError
from rest_framework.request import Request

from .. import services
from ..access import Role, global_role, robot_of, role_named
from ..models import Building, Membership
from ..serializers import MembershipSerializer
from .lookups import building_for


def members_of(request: Request, code: str, need: Role) -> Building:
    """Building ``code`` whose members the caller may see (``building_for``); robots see
    none (PermissionDenied): who works in a building is people's business."""
    building = building_for(request, code, need)
    if robot_of(request.user) is not None:
        raise PermissionDenied("Robots do not read a building's members.")
    return building


class MemberList(generics.ListCreateAPIView[Membership]):
    """A building's members and their roles; its admins add members (POST {username, role})."""

    serializer_class = MembershipSerializer
    pagination_class = None

    def get_queryset(self) -> QuerySet[Membership]:
        need = Role.VIEWER if self.request.method == "GET" else Role.ADMIN
        building = members_of(self.request, self.kwargs["building"], need)
        return building.memberships.select_related("user").order_by("user__username")

    def get_serializer_context(self) -> dict[str, Any]:
        context = {**super().get_serializer_context()}
        if self.request.method == "POST":
            context["building"] = building_for(self.request, self.kwargs["building"], Role.ADMIN)
        return context

    def perform_create(self, serializer: Any) -> None:
        serializer.save(building=serializer.context["building"])


class MemberDetail(generics.RetrieveUpdateDestroyAPIView[Membership]):
    """One member of a building: its admins change their role (PATCH {role}) or remove them.

    A change that would leave the building without an admin member is refused (400)."""

    serializer_class = MembershipSerializer
    http_method_names = ["get", "patch", "delete", "head", "options"]

    def get_object(self) -> Membership:
        need = Role.VIEWER if self.request.method == "GET" else Role.ADMIN
        building = members_of(self.request, self.kwargs["building"], need)
        member = building.memberships.select_related("user")
        found = member.filter(user__username=self.kwargs["username"]).first()
        if found is None:
            raise NotFound("No such member of this building.")
        return found

    def perform_update(self, serializer: Any) -> None:
        if "role" not in serializer.validated_data:
            raise ValidationError({"role": ["This field is required."]})
        role = role_named(serializer.validated_data["role"])
        with services.locked_building(serializer.instance.building):
            _keep_an_admin(self.request, serializer.instance, role, "role")
            serializer.save()

    def perform_destroy(self, instance: Membership) -> None:
        with services.locked_building(instance.building):
            _keep_an_admin(self.request, instance, Role.NONE, "username")
            instance.delete()


def _effective_role(membership: Membership) -> Role:
    return role_named(membership.role) or global_role(membership.user)


def _keep_an_admin(request: Request, membership: Membership, new: Role, field: str) -> None:
    """Refuse to take the last admin role of a building away (no one could then manage it).

    Called with the building locked: the caller's role and the members' are read again, as
    a request at the same instant may have changed them (PermissionDenied if the caller is
    no admin any more, ValidationError if no admin would be left).
    """
    building_for(request, membership.building.code, Role.ADMIN)
    try:
        membership.refresh_from_db(fields=["role"])
    except Membership.DoesNotExist:
        raise NotFound("No such member of this building.") from None
    if new >= Role.ADMIN or _effective_role(membership) < Role.ADMIN:
        return
    others = membership.building.memberships.exclude(pk=membership.pk).select_related("user")
    if not any(_effective_role(other) >= Role.ADMIN for other in others):
        raise ValidationError({field: ["The building would have no admin left."]})
