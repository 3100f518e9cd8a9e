"""Who may do what: a person's role is per building, held by their membership of it.

A person's groups ``admin``, ``operator`` and ``viewer`` say whether they use CloudNav
at all and what they may do outside any building (the admin group creates buildings and
registers robots): their global role is the strongest of those groups. In a building
they are a member of, their role is the membership's (``Membership.role``; an empty one
is their global role), so one person may be an operator in one building and a viewer in
another. Superusers are admins everywhere. A person with no group has no role anywhere.
A robot sees exactly the buildings it is registered for, and edits nothing.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any

from django.db.models import Q, QuerySet

from .models import Building


class Role(IntEnum):
    NONE = 0
    VIEWER = 1
    OPERATOR = 2
    ADMIN = 3


GROUP_ROLES = {"admin": Role.ADMIN, "operator": Role.OPERATOR, "viewer": Role.VIEWER}
ROLE_NAMES = {role: name for name, role in GROUP_ROLES.items()}


def role_named(name: str) -> Role:
    """The role a membership's ``role`` names; NONE for an empty or unknown name."""
    return GROUP_ROLES.get(name, Role.NONE)


def robot_of(principal: Any) -> Any:
    """Return the robot behind a principal, or None for a person."""
    return getattr(principal, "robot", None)


def global_role(user: Any) -> Role:
    """Return a person's role from their groups, cached on the user object."""
    if user is None or not user.is_authenticated or robot_of(user) is not None:
        return Role.NONE
    if user.is_superuser:
        return Role.ADMIN
    cached = getattr(user, "_cloudnav_role", None)
    if cached is None:
        names = user.groups.values_list("name", flat=True)
        cached = max((GROUP_ROLES.get(n, Role.NONE) for n in names), default=Role.NONE)
        user._cloudnav_role = cached
    return Role(cached)


def buildings_for(principal: Any) -> QuerySet[Building]:
    """Return the buildings a user or robot may see at all."""
    robot = robot_of(principal)
    if robot is not None:
        assigned: QuerySet[Building] = robot.buildings.all()
        return assigned
    role = global_role(principal)
    if role is Role.NONE:
        return Building.objects.none()
    if principal.is_superuser:
        return Building.objects.all()
    return Building.objects.filter(members=principal)


def buildings_where(principal: Any, need: Role) -> QuerySet[Building]:
    """Return the buildings where ``principal`` holds at least ``need`` (one query)."""
    visible = buildings_for(principal)
    if need <= Role.VIEWER or principal.is_superuser:
        return visible
    if robot_of(principal) is not None:
        return Building.objects.none()
    named = [name for name, role in GROUP_ROLES.items() if role >= need]
    held = Q(memberships__role__in=named)
    if global_role(principal) >= need:
        held |= Q(memberships__role="")  # the group's role
    return Building.objects.filter(held, memberships__user=principal)


def role_in(principal: Any, building: Building) -> Role:
    """Return what ``principal`` may do in ``building``: NONE if it may not even see it."""
    robot = robot_of(principal)
    if robot is not None:
        visible = robot.buildings.filter(pk=building.pk).exists()
        return Role.VIEWER if visible else Role.NONE
    role = global_role(principal)
    if role is Role.NONE or principal.is_superuser:
        return role
    membership = building.memberships.filter(user=principal.pk).values_list("role", flat=True)
    held = membership.first()
    if held is None:
        return Role.NONE
    return role_named(held) if held else role


def may_create_buildings(principal: Any) -> bool:
    return global_role(principal) >= Role.ADMIN
