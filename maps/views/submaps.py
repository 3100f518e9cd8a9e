"""Sub-maps: upload (or preview) a map_server pair, read, edit and delete one, its image,
grid and map_server export, and the bundle robots fetch on entering it."""

from __future__ import annotations

import io
import zipfile
from typing import Any

from django.db.models import QuerySet
from django.http import HttpResponse, HttpResponseBase
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, OpenApiResponse, extend_schema
from rest_framework import generics, status
from rest_framework.parsers import FormParser, JSONParser, MultiPartParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from .. import services
from ..access import Role, robot_of
from ..domain.mapfile import export_map, map_yaml_text
from ..models import SubMap
from ..serializers import SubMapSerializer, SubMapUpdateSerializer, SubMapUploadSerializer
from ..signals import bundle_fetched
from .lookups import building_for, submap_for
from .map_files import grid_response, image_response


class SubMapList(generics.ListCreateAPIView[SubMap]):
    parser_classes = [MultiPartParser, FormParser]

    def get_serializer_class(self) -> Any:
        return SubMapUploadSerializer if self.request.method == "POST" else SubMapSerializer

    def get_queryset(self) -> QuerySet[SubMap]:
        building = building_for(self.request, self.kwargs["building"])
        return building.submaps.defer("image").select_related("building")

    @extend_schema(
        request=SubMapUploadSerializer,
        responses={
            201: SubMapSerializer,
            200: OpenApiResponse(
                description="the map replaced (replace=true): the sub-map; or, with "
                "dry_run=true, the preview of what would be stored"
            ),
            409: OpenApiResponse(description="the code exists and replace was not sent"),
        },
    )
    def post(self, request: Request, building: str) -> Response:
        """Upload a map_server pair (or a zip of it), or preview it (dry_run).

        An existing code has its map replaced only with replace=true (else 409).
        """
        target = building_for(request, building, Role.ADMIN)
        upload = SubMapUploadSerializer(data=request.data)
        upload.is_valid(raise_exception=True)
        data = upload.validated_data
        loaded = upload.load()
        if data["dry_run"]:
            return Response(services.preview_upload(target, data.get("code"), loaded))
        fields = {k: v for k, v in data.items() if k in ("name", "node_x", "node_y")}
        submap, created = services.save_submap(
            target,
            data["code"],
            loaded,
            replace=data["replace"],
            author=request.user,
            note=data.get("note", ""),
            **fields,
        )
        answer = status.HTTP_201_CREATED if created else status.HTTP_200_OK
        return Response(SubMapSerializer(submap).data, status=answer)


class SubMapDetail(APIView):
    parser_classes = [JSONParser]

    @extend_schema(responses=SubMapSerializer)
    def get(self, request: Request, building: str, map: str) -> Response:
        return Response(SubMapSerializer(submap_for(request, building, map)).data)

    @extend_schema(request=SubMapUpdateSerializer, responses=SubMapSerializer)
    def patch(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map, Role.ADMIN)
        changes = SubMapUpdateSerializer(data=request.data, partial=True)
        changes.is_valid(raise_exception=True)
        submap = services.update_submap(submap, changes.validated_data, author=request.user)
        return Response(SubMapSerializer(submap).data)

    def delete(self, request: Request, building: str, map: str) -> Response:
        submap_for(request, building, map, Role.ADMIN).delete()
        return Response(status=status.HTTP_204_NO_CONTENT)


class SubMapImage(APIView):
    """The image exactly as uploaded."""

    @extend_schema(responses={(200, "image/*"): OpenApiTypes.BINARY})
    def get(self, request: Request, building: str, map: str) -> HttpResponse:
        return image_response(submap_for(request, building, map))


class SubMapGrid(APIView):
    """The sub-map as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON (heavy work)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str) -> HttpResponseBase:
        submap = submap_for(request, building, map)
        return grid_response(request, submap, submap.map_id)


class SubMapExport(APIView):
    """A zip holding ``<code>.yaml`` and ``<code>.pgm`` that map_server loads to the same grid."""

    @extend_schema(responses={(200, "application/zip"): OpenApiTypes.BINARY})
    def get(self, request: Request, building: str, map: str) -> HttpResponse:
        submap = submap_for(request, building, map)
        pgm, meta = export_map(services.grid_of(submap), services.metadata_of(submap), f"{map}.pgm")
        archive = io.BytesIO()
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as bundle:
            bundle.writestr(f"{map}.yaml", map_yaml_text(meta))
            bundle.writestr(f"{map}.pgm", pgm)
        response = HttpResponse(archive.getvalue(), content_type="application/zip")
        response["Content-Disposition"] = f'attachment; filename="{building}_{map}.zip"'
        return response


class SubMapBundle(APIView):
    """Everything a robot needs on entering a sub-map, with an ETag for conditional requests."""

    @extend_schema(
        parameters=[OpenApiParameter("If-None-Match", str, OpenApiParameter.HEADER)],
        responses={200: OpenApiTypes.OBJECT, 304: None},
    )
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        etag = services.bundle_etag(submap)
        if etag in _etags(request.headers.get("If-None-Match", "")):
            return Response(status=status.HTTP_304_NOT_MODIFIED, headers={"ETag": etag})
        robot = robot_of(request.user)
        if robot is not None:
            bundle_fetched.send(SubMap, submap=submap, robot=robot.name)
        return Response(services.bundle_of(submap), headers={"ETag": etag})


def _etags(header: str) -> set[str]:
    return {tag.strip().removeprefix("W/") for tag in header.split(",") if tag.strip()}
