"""The objects a request names (a building, a sub-map, a tag), found only when the caller
holds the role asked for there: NotFound or PermissionDenied otherwise."""

from __future__ import annotations

from rest_framework.exceptions import NotFound, PermissionDenied
from rest_framework.request import Request

from ..access import Role, robot_of, role_in
from ..models import Building, EnvironmentalTag, SubMap


def building_for(request: Request, code: str, need: Role = Role.VIEWER) -> Building:
    """Return building ``code`` if the caller holds at least ``need`` there.

    Raises NotFound when a person may not see it (its existence is not revealed) and
    PermissionDenied when a robot is not registered for it or a person's role is too low.
    """
    building = Building.objects.filter(code=code).first()
    role = role_in(request.user, building) if building is not None else Role.NONE
    if building is not None and role >= need:
        return building
    if building is not None and (role > Role.NONE or robot_of(request.user) is not None):
        raise PermissionDenied("You may not do this in this building.")
    raise NotFound("No such building.")


def submap_for(request: Request, building: str, code: str, need: Role = Role.VIEWER) -> SubMap:
    submap = building_for(request, building, need).submaps.filter(code=code).first()
    if submap is None:
        raise NotFound("No such sub-map.")
    return submap


def tag_for(request: Request, pk: int, need: Role = Role.VIEWER) -> EnvironmentalTag:
    tag = (
        EnvironmentalTag.objects.select_related("building", "submap", "links_to")
        .filter(pk=pk)
        .first()
    )
    if tag is None:
        raise NotFound("No such tag.")
    building_for(request, tag.building.code, need)
    return tag
