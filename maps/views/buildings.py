"""Buildings: the list the caller may see (admins create them) and one building."""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from rest_framework import generics
from rest_framework.exceptions import PermissionDenied

from ..access import Role, buildings_for, may_create_buildings
from ..models import Building
from ..serializers import BuildingSerializer
from .lookups import building_for


class BuildingList(generics.ListCreateAPIView[Building]):
    serializer_class = BuildingSerializer

    def get_queryset(self) -> QuerySet[Building]:
        return buildings_for(self.request.user).prefetch_related("members")

    def perform_create(self, serializer: Any) -> None:
        if not may_create_buildings(self.request.user):
            raise PermissionDenied("Only admins create buildings.")
        building = serializer.save()
        building.members.add(self.request.user, through_defaults={"role": "admin"})


class BuildingDetail(generics.RetrieveUpdateDestroyAPIView[Building]):
    serializer_class = BuildingSerializer
    lookup_field = "code"
    lookup_url_kwarg = "building"

    def get_object(self) -> Building:
        need = Role.VIEWER if self.request.method == "GET" else Role.ADMIN
        return building_for(self.request, self.kwargs["building"], need)
