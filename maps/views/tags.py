"""Environmental tags: list, create, read, edit, and print them at true physical size."""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from django.http import HttpResponseBase
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework import generics
from rest_framework.exceptions import NotFound, PermissionDenied
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from cloudnav_django.heavy import heavy_response

from .. import services
from ..access import Role, buildings_for, global_role
from ..domain.tagart import print_memory, render_tag_pdf, render_tag_png
from ..models import EnvironmentalTag
from ..serializers import TagSerializer
from .lookups import building_for, tag_for


class TagList(generics.ListCreateAPIView[EnvironmentalTag]):
    serializer_class = TagSerializer

    def get_queryset(self) -> QuerySet[EnvironmentalTag]:
        tags = EnvironmentalTag.objects.filter(building__in=buildings_for(self.request.user))
        if code := self.request.query_params.get("building"):
            tags = tags.filter(building__code=code)
        if code := self.request.query_params.get("map"):
            tags = tags.filter(submap__code=code)
        return tags.select_related("building", "submap__building", "links_to__building")

    def create(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        """Check that the caller administers the named building before validating the
        tag, so a refusal tells nothing of another building's sub-maps or markers."""
        code = request.data.get("building") if hasattr(request.data, "get") else None
        if isinstance(code, str):
            building_for(request, code, Role.ADMIN)
        elif global_role(request.user) < Role.ADMIN:
            raise PermissionDenied("Only admins create tags.")
        return super().create(request, *args, **kwargs)

    def perform_create(self, serializer: Any) -> None:
        building_for(self.request, serializer.validated_data["building"].code, Role.ADMIN)
        serializer.save()


class TagDetail(generics.RetrieveUpdateDestroyAPIView[EnvironmentalTag]):
    serializer_class = TagSerializer

    def get_object(self) -> EnvironmentalTag:
        return tag_for(
            self.request,
            self.kwargs["pk"],
            Role.VIEWER if self.request.method == "GET" else Role.ADMIN,
        )


class TagPrint(APIView):
    """One tag at true physical size, as PNG (with its DPI) or PDF."""

    @extend_schema(
        responses={
            (200, "image/png"): OpenApiTypes.BINARY,
            (200, "application/pdf"): OpenApiTypes.BINARY,
        }
    )
    def get(self, request: Request, pk: int, extension: str) -> HttpResponseBase:
        tag = tag_for(request, pk)
        art = services.tag_art(tag)
        response = heavy_response(
            request,
            print_memory([art.size]),
            lambda: render_tag_png(art) if extension == "png" else render_tag_pdf([art]),
            "image/png" if extension == "png" else "application/pdf",
        )
        response["Content-Disposition"] = (
            f'inline; filename="tag_{tag.building.code}_{tag.marker_id}.{extension}"'
        )
        return response


class BuildingTagSheet(APIView):
    """Every tag of a building, packed on A4 pages at true physical size."""

    @extend_schema(responses={(200, "application/pdf"): OpenApiTypes.BINARY})
    def get(self, request: Request, building: str) -> HttpResponseBase:
        target = building_for(request, building)
        tags = target.tags.select_related("building", "submap__building", "links_to__building")
        if not tags:
            raise NotFound("This building has no tags.")
        arts = [services.tag_art(t) for t in tags]
        need = print_memory([art.size for art in arts])
        response = heavy_response(request, need, lambda: render_tag_pdf(arts), "application/pdf")
        response["Content-Disposition"] = f'inline; filename="tags_{target.code}.pdf"'
        return response
