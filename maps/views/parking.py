"""A building's parking spots: members read them, its admins edit them."""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from rest_framework import generics
from rest_framework.exceptions import NotFound

from ..access import Role
from ..models import Building, ParkingSpot
from ..serializers import ParkingSpotSerializer
from .lookups import building_for


class _BuildingsParking(generics.GenericAPIView[ParkingSpot]):
    """The building of the URL, which members read and its admins edit."""

    def _building(self) -> Building:
        need = Role.VIEWER if self.request.method == "GET" else Role.ADMIN
        found: Building | None = getattr(self, "_found", None)
        if found is None:
            found = self._found = building_for(self.request, self.kwargs["building"], need)
        return found

    def get_serializer_context(self) -> dict[str, Any]:
        return {**super().get_serializer_context(), "building": self._building()}


class ParkingSpotList(_BuildingsParking, generics.ListCreateAPIView[ParkingSpot]):
    """``/api/buildings/{code}/parking/``: members read the building's parking spots,
    its admins add them."""

    serializer_class = ParkingSpotSerializer
    pagination_class = None

    def get_queryset(self) -> QuerySet[ParkingSpot]:
        return self._building().parking_spots.select_related("submap__building")

    def perform_create(self, serializer: Any) -> None:
        serializer.save(building=self._building())


class ParkingSpotDetail(_BuildingsParking, generics.RetrieveUpdateDestroyAPIView[ParkingSpot]):
    """``/api/buildings/{code}/parking/{id}/``: members read a spot, admins move, rename
    or delete it."""

    serializer_class = ParkingSpotSerializer

    def get_object(self) -> ParkingSpot:
        spot = self._building().parking_spots.filter(pk=self.kwargs["pk"]).first()
        if spot is None:
            raise NotFound("No such parking spot.")
        return spot
