"""REST adapters of the map store: parse, authorise, call one service, answer."""

from __future__ import annotations

import io
import zipfile
from typing import Any

from django.db.models import QuerySet
from django.http import HttpResponse, HttpResponseBase
from django.utils.http import content_disposition_header, quote_etag
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, OpenApiResponse, extend_schema
from rest_framework import generics, status
from rest_framework.exceptions import NotFound, PermissionDenied, ValidationError
from rest_framework.parsers import FormParser, JSONParser, MultiPartParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from cloudnav_web.heavy import heavy_response

from . import services, versions
from .access import (
    Role,
    buildings_for,
    buildings_where,
    global_role,
    may_create_buildings,
    robot_of,
    role_in,
    role_named,
)
from .domain.mapfile import export_map, map_yaml_text, occupancy_grid_json
from .domain.tagart import print_memory, render_tag_pdf, render_tag_png
from .domain.topology import Coverage, Edge
from .models import Building, EnvironmentalTag, MapFile, Membership, SubMap
from .serializers import (
    BuildingSerializer,
    CoverageSerializer,
    MembershipSerializer,
    RouteSerializer,
    SubMapSerializer,
    SubMapUpdateSerializer,
    SubMapUploadSerializer,
    TagSerializer,
    TopologySerializer,
    VersionComparisonSerializer,
    VersionSerializer,
)
from .signals import bundle_fetched
from .visual import service as visual
from .visual import store as visual_store
from .visual.lanes import Caller


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


# Buildings


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


# Members and their roles


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


# Sub-maps


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


def image_response(map_file: MapFile) -> HttpResponse:
    response = HttpResponse(
        bytes(map_file.image), content_type=services.image_content_type(map_file)
    )
    # Names stored before control characters were refused may hold CR or LF.
    response["Content-Disposition"] = (
        content_disposition_header(False, map_file.image_name) or "inline"
    )
    response["ETag"] = quote_etag(map_file.version)
    return response


# Bytes a map cell costs while its grid is converted and written as JSON (heavy work).
GRID_BYTES_PER_CELL = 16


class SubMapGrid(APIView):
    """The sub-map as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON (heavy work)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str) -> HttpResponseBase:
        submap = submap_for(request, building, map)
        return grid_response(request, submap, submap.map_id)


def grid_response(request: Request, map_file: MapFile, frame_id: str) -> HttpResponseBase:
    """``map_file``'s grid as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON, under the
    heavy-work budget."""

    def build() -> bytes:
        meta = services.metadata_of(map_file)
        return occupancy_grid_json(services.grid_of(map_file), meta, frame_id=frame_id)

    need = map_file.width * map_file.height * GRID_BYTES_PER_CELL
    return heavy_response(request, need, build, "application/json")


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


# Versions


class VersionList(APIView):
    """A sub-map's versions, newest first (who, when, why), the current one's number and
    the tags that stand in an occupied cell of it."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        return Response(
            {
                "map_id": submap.map_id,
                "current": submap.revision,
                "buried_tags": versions.buried_tags_of(submap),
                "versions": VersionSerializer(versions.history(submap), many=True).data,
            }
        )


class VersionDetail(APIView):
    @extend_schema(responses=VersionSerializer)
    def get(self, request: Request, building: str, map: str, number: int) -> Response:
        submap = submap_for(request, building, map)
        return Response(VersionSerializer(versions.version_of(submap, number)).data)


class VersionImage(APIView):
    """An old version's image, as it was made."""

    @extend_schema(responses={(200, "image/*"): OpenApiTypes.BINARY})
    def get(self, request: Request, building: str, map: str, number: int) -> HttpResponse:
        return image_response(versions.version_of(submap_for(request, building, map), number))


class VersionGrid(APIView):
    """An old version as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON (heavy work)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str, number: int) -> HttpResponseBase:
        submap = submap_for(request, building, map)
        return grid_response(request, versions.version_of(submap, number), submap.map_id)


class VersionRollback(APIView):
    """Make an earlier version current again: a new version with its map (admins)."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={201: VersionSerializer})
    def post(self, request: Request, building: str, map: str, number: int) -> Response:
        submap = submap_for(request, building, map, Role.ADMIN)
        note = str(request.data.get("note", "")) if isinstance(request.data, dict) else ""
        made = versions.rollback(submap, number, request.user, note)
        return Response(VersionSerializer(made).data, status=status.HTTP_201_CREATED)


# Changed cells listed in a comparison at most; the counts are always whole.
COMPARISON_CELLS = 50_000


class VersionComparison(APIView):
    """How version ``to`` differs from version ``from``: cells that became occupied
    (``added``) or free (``removed``), as ``[row, col]`` of ``to``'s grid."""

    @extend_schema(
        parameters=[
            OpenApiParameter("from", int, required=True),
            OpenApiParameter("to", int, required=True),
        ],
        responses=VersionComparisonSerializer,
    )
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        numbers = VersionComparisonSerializer.numbers(request.query_params)
        diff = versions.compare(submap, numbers["from"], numbers["to"])
        return Response(
            {
                "from": numbers["from"],
                "to": numbers["to"],
                "added": len(diff.added),
                "removed": len(diff.removed),
                "unknown_changed": diff.unknown_changed,
                "compared": diff.compared,
                "truncated": len(diff.added) + len(diff.removed) > COMPARISON_CELLS,
                "cells": {
                    "added": diff.added[:COMPARISON_CELLS].tolist(),
                    "removed": diff.removed[: max(0, COMPARISON_CELLS - len(diff.added))].tolist(),
                },
            }
        )


# The visual map


class SubMapKeyframes(APIView):
    """A sub-map's keyframes: robots of the building send them (``POST``, queued: 202),
    anyone who sees the building lists their poses (``GET``), admins clear them."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={202: OpenApiTypes.OBJECT})
    def post(self, request: Request, building: str, map: str) -> Response:
        """``{image, depth, pose: {x, y, yaw}, camera_info?, mount?}``; 503 when the
        ingestion queue is full."""
        submap = submap_for(request, building, map)
        robot = robot_of(request.user)
        if robot is None:
            raise PermissionDenied("Only robots send keyframes.")
        if not isinstance(request.data, dict):
            raise ValidationError({"detail": "a JSON object is required"})
        visual.accept_keyframe(submap, robot.name, request.data)
        return Response({"queued": True}, status=status.HTTP_202_ACCEPTED)

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        return Response({"map_id": submap.map_id, "keyframes": visual_store.coverage(submap)})

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def delete(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map, Role.ADMIN)
        return Response({"removed": visual_store.clear(submap)})


class Relocalise(APIView):
    """``/cloudnav/relocalise`` over REST: where the images were taken, among the
    keyframes of the buildings the caller may relocalise in (a robot: its own; a person:
    where they may drive), ``building`` narrowing it; 403 when that is none. Answered on
    the relocalisation lanes the rosbridge service uses (robots first; 429 or 503 with
    Retry-After when the caller's share or the lane is full)."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def post(self, request: Request) -> Response:
        if not isinstance(request.data, dict):
            raise ValidationError({"detail": "a JSON object is required"})
        code = request.data.get("building")
        if code is not None and not isinstance(code, str):
            raise ValidationError({"building": ["a building code is required"]})
        robot = robot_of(request.user)
        if robot is not None:
            allowed = buildings_for(request.user)
            caller = Caller(f"robot:{robot.name}", robot=True)
        else:
            allowed = buildings_where(request.user, Role.OPERATOR)
            caller = Caller(f"user:{request.user.get_username()}", robot=False)
        buildings = visual.buildings_to_search(allowed.values_list("pk", flat=True), code)
        return Response(visual.relocalise_queued(caller, buildings, request.data).result())


# Topology and routes


class Topology(APIView):
    parser_classes = [JSONParser]

    @extend_schema(responses=TopologySerializer)
    def get(self, request: Request, building: str) -> Response:
        return Response(services.topology_document(building_for(request, building)))

    @extend_schema(request=TopologySerializer, responses=TopologySerializer)
    def put(self, request: Request, building: str) -> Response:
        """Replace the whole graph; it is validated first and stored whole or not at all."""
        target = building_for(request, building, Role.ADMIN)
        positions, edges = _proposed_topology(request)
        services.replace_topology(target, positions, edges)
        return Response(services.topology_document(target))


def _proposed_topology(request: Request) -> tuple[dict[str, tuple[float, float]], list[Edge]]:
    """Node positions and edges of a topology document in the body. Raises ValidationError."""
    document = TopologySerializer(data=request.data)
    document.is_valid(raise_exception=True)
    positions = {n["code"]: (n["x"], n["y"]) for n in document.validated_data.get("nodes", [])}
    edges = [Edge(e["a"], e["b"], e["cost"]) for e in document.validated_data["edges"]]
    return positions, edges


class TopologyValidation(APIView):
    """Edges no tag lets a robot cross (routes never use them), and tags that link along
    no edge: of the stored graph (GET), or of a graph an editor is about to save (POST
    the document PUT takes; nothing is stored)."""

    parser_classes = [JSONParser]

    @extend_schema(responses=CoverageSerializer)
    def get(self, request: Request, building: str) -> Response:
        return Response(_coverage_document(services.coverage_of(building_for(request, building))))

    @extend_schema(request=TopologySerializer, responses=CoverageSerializer)
    def post(self, request: Request, building: str) -> Response:
        target = building_for(request, building, Role.ADMIN)
        _, edges = _proposed_topology(request)
        return Response(_coverage_document(services.coverage_of(target, edges)))


def _coverage_document(coverage: Coverage) -> dict[str, Any]:
    return {
        "valid": not coverage.uncrossable and not coverage.dangling,
        "uncrossable_edges": [{"from": a, "to": b} for a, b in coverage.uncrossable],
        "dangling_tags": [
            {"marker_id": t.marker_id, "map": t.submap, "links_to": t.links_to}
            for t in coverage.dangling
        ],
    }


class Route(APIView):
    @extend_schema(
        parameters=[
            OpenApiParameter("from", str, required=True),
            OpenApiParameter("to", str, required=True),
        ],
        responses=RouteSerializer,
    )
    def get(self, request: Request, building: str) -> Response:
        target = building_for(request, building)
        missing = {
            f: ["This parameter is required."]
            for f in ("from", "to")
            if not request.query_params.get(f)
        }
        if missing:
            raise ValidationError(missing)
        steps = services.route_in(target, request.query_params["from"], request.query_params["to"])
        return Response({"building": target.code, "steps": [_step(target, s) for s in steps]})


def _step(building: Building, step: Any) -> dict[str, Any]:
    tag = step.tag and building.tags.select_related("links_to").get(marker_id=step.tag.marker_id)
    return {
        "map": step.submap,
        "map_id": f"{building.code}/{step.submap}",
        "tag": tag and {**TagSerializer(tag).data, "building": building.code},
    }


# Tags


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
