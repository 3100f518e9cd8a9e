"""REST adapters of mapping sessions: start one for a robot, watch its map grow, finish,
resume, discard, publish the map as a sub-map or a new version of one."""

from __future__ import annotations

import io
import zipfile
from typing import Any

from django.http import HttpResponse, HttpResponseBase
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import serializers, status
from rest_framework.exceptions import NotFound
from rest_framework.parsers import JSONParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from cloudnav_django.heavy import heavy_response

from .. import versions
from ..access import Role, buildings_for
from ..domain.mapfile import map_yaml_text, occupancy_grid_json
from ..domain.visual_cloud import FEED_KEYFRAMES, MAX_POINTS, PLY_VERTEX, feed_bytes
from ..models import ChangeProposal, MappingSession
from ..serializers import VersionSerializer
from ..views.lookups import building_for, submap_for
from ..views.map_files import GRID_BYTES_PER_CELL
from . import maps3d, sessions, upkeep


class StartSerializer(serializers.Serializer[Any]):
    robot = serializers.CharField()
    building = serializers.CharField()
    code = serializers.RegexField(r"^[A-Za-z][A-Za-z0-9_]*$", max_length=40)
    update = serializers.BooleanField(  # type: ignore[assignment]
        default=False, help_text="true: a new version of the existing sub-map `code`"
    )
    kind = serializers.ChoiceField(
        choices=MappingSession.KINDS,
        default=MappingSession.LASER,
        help_text="laser: from scans and odometry; visual: from an RGB-D camera's image and depth",
    )


class SessionSerializer(serializers.ModelSerializer[MappingSession]):
    robot = serializers.CharField(source="robot.name")
    building = serializers.CharField(source="building.code")
    started_by: serializers.SlugRelatedField[Any] = serializers.SlugRelatedField(
        slug_field="username", read_only=True
    )
    map_id = serializers.SerializerMethodField()
    size = serializers.SerializerMethodField()

    class Meta:
        model = MappingSession
        fields = [
            "id",
            "robot",
            "building",
            "code",
            "kind",
            "map_id",
            "based_on",
            "state",
            "reason",
            "started_by",
            "created",
            "updated",
            "snapshot",
            "origin_x",
            "origin_y",
            "resolution",
            "size",
            "path",
            "stats",
        ]

    def get_map_id(self, session: MappingSession) -> str:
        return f"{session.building.code}/{session.code}"

    def get_size(self, session: MappingSession) -> list[int]:
        """[width, height] of the map so far, in cells ([0, 0] before the first)."""
        return list(sessions.size_of(session))


def session_for(request: Request, pk: int, need: Role = Role.VIEWER) -> MappingSession:
    """Session ``pk`` if the caller holds ``need`` in its building; NotFound otherwise
    (or PermissionDenied for a role too low, as ``building_for``)."""
    session = (
        MappingSession.objects.select_related("robot", "building", "submap", "started_by")
        .filter(pk=pk)
        .first()
    )
    if session is None:
        raise NotFound("No such mapping session.")
    building_for(request, session.building.code, need)
    return session


def _document(session: MappingSession) -> dict[str, Any]:
    return dict(SessionSerializer(session).data)


class SessionList(APIView):
    """Mapping sessions of the buildings one sees (``?building=``, ``?robot=``); POST
    starts one (operators and admins)."""

    parser_classes = [JSONParser]

    @extend_schema(
        parameters=[OpenApiParameter("building", str), OpenApiParameter("robot", str)],
        responses=SessionSerializer(many=True),
    )
    def get(self, request: Request) -> Response:
        found = MappingSession.objects.filter(building__in=buildings_for(request.user))
        if code := request.query_params.get("building"):
            found = found.filter(building__code=code)
        if name := request.query_params.get("robot"):
            found = found.filter(robot__name=name)
        found = found.select_related("robot", "building", "started_by").defer("keyframes")
        return Response([_document(s) for s in found[:50]])

    @extend_schema(request=StartSerializer, responses={201: SessionSerializer})
    def post(self, request: Request) -> Response:
        asked = StartSerializer(data=request.data)
        asked.is_valid(raise_exception=True)
        data = asked.validated_data
        building = building_for(request, data["building"], Role.OPERATOR)
        robot = building.robots.filter(name=data["robot"]).first()
        if robot is None:
            raise NotFound(f"No robot {data['robot']} in {building.code}.")
        session = sessions.start(
            robot, building, data["code"], request.user, data["update"], data["kind"]
        )
        return Response(_document(session), status=status.HTTP_201_CREATED)


class SessionDetail(APIView):
    @extend_schema(responses=SessionSerializer)
    def get(self, request: Request, pk: int) -> Response:
        return Response(_document(session_for(request, pk)))


class SessionGrid(APIView):
    """The map so far as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON (heavy work)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, pk: int) -> HttpResponseBase:
        session = session_for(request, pk)
        width, height = sessions.size_of(session)

        def build() -> bytes:
            loaded = sessions.candidate(session)
            return occupancy_grid_json(loaded.grid, loaded.meta, frame_id=f"mapping/{session.pk}")

        need = width * height * GRID_BYTES_PER_CELL
        return heavy_response(request, need, build, "application/json")


class SessionCandidate(APIView):
    """The map so far as a map_server pair: a zip of ``<code>.yaml`` and ``<code>.pgm``."""

    @extend_schema(responses={(200, "application/zip"): OpenApiTypes.BINARY})
    def get(self, request: Request, pk: int) -> HttpResponse:
        session = session_for(request, pk)
        loaded = sessions.candidate(session)
        archive = io.BytesIO()
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as bundle:
            bundle.writestr(f"{session.code}.yaml", map_yaml_text(loaded.meta))
            bundle.writestr(loaded.meta.image, loaded.image_bytes)
        response = HttpResponse(archive.getvalue(), content_type="application/zip")
        response["Content-Disposition"] = f'attachment; filename="mapping_{session.pk}.zip"'
        return response


MAP3D_NAMES = (maps3d.CLOUD, maps3d.OCTOMAP)
OCTOMAP_BYTES_PER_POINT = 64
"""An estimate of the memory the OctoMap's tree holds per point inserted, for the budget."""


class SessionMap3D(APIView):
    """A visual session's 3D map so far: ``cloud.ply`` (its coloured point cloud, binary
    PLY, one point per 5 cm cube) or ``octomap.bt`` (an OctoMap); heavy work, made from
    the state the session last saved. 409 for a laser session."""

    @extend_schema(responses={(200, "application/octet-stream"): OpenApiTypes.BINARY})
    def get(self, request: Request, pk: str, name: str) -> HttpResponseBase:
        session = session_for(request, int(pk))
        view = maps3d.view_of(session)
        points = sum(len(c) for c in view.clouds)
        per_point = PLY_VERTEX.itemsize * 4 if name == maps3d.CLOUD else OCTOMAP_BYTES_PER_POINT
        need = min(points, 4 * MAX_POINTS) * per_point
        response = heavy_response(
            request, need, lambda: maps3d.made(view, name), "application/octet-stream"
        )
        return _attachment(response, f"mapping_{session.pk}_{name}")


class SessionPoints(APIView):
    """The live 3D view's feed (``visual_cloud.feed_bytes``): every keyframe's pose, the
    loop closures, and the clouds of up to 8 keyframes from ``from`` on."""

    @extend_schema(
        parameters=[OpenApiParameter("from", int, description="the first keyframe sent")],
        responses={(200, "application/octet-stream"): OpenApiTypes.BINARY},
    )
    def get(self, request: Request, pk: int) -> HttpResponse:
        session = session_for(request, pk)
        start = request.query_params.get("from", "0")
        if not start.isdigit() or len(start) > 9:
            raise serializers.ValidationError({"from": ["a keyframe's number (0, 1, ...)"]})
        view = maps3d.view_of(session)
        body = feed_bytes(view.clouds, view.poses, view.loops, int(start), FEED_KEYFRAMES)
        return HttpResponse(body, content_type="application/octet-stream")


class VersionMap3D(APIView):
    """The 3D map (``cloud.ply`` or ``octomap.bt``) a visual session was published with
    as this version; 404 for a version made otherwise."""

    @extend_schema(responses={(200, "application/octet-stream"): OpenApiTypes.BINARY})
    def get(
        self, request: Request, building: str, map: str, number: str, name: str
    ) -> HttpResponseBase:
        submap = submap_for(request, building, map)
        version = versions.version_of(submap, int(number))
        data = maps3d.stored(version, name)
        if data is None:
            raise NotFound(f"{submap.map_id} v{number} was not mapped by a camera: no 3D map.")
        response = HttpResponse(data, content_type="application/octet-stream")
        return _attachment(response, f"{submap.building.code}_{submap.code}_v{number}_{name}")


def _attachment(response: HttpResponseBase, filename: str) -> HttpResponseBase:
    response["Content-Disposition"] = f'attachment; filename="{filename}"'
    return response


# What each action does: the state it leads to and the states it may start from.
ACTIONS = {
    "finish": (MappingSession.FINISHED, (MappingSession.RUNNING, MappingSession.INTERRUPTED)),
    "resume": (MappingSession.RUNNING, (MappingSession.INTERRUPTED,)),
    "discard": (
        MappingSession.DISCARDED,
        (MappingSession.RUNNING, MappingSession.INTERRUPTED, MappingSession.FINISHED),
    ),
}


class SessionAction(APIView):
    """``finish`` (the map becomes a candidate), ``resume`` an interrupted session,
    ``discard``; operators and admins."""

    parser_classes = [JSONParser]

    @extend_schema(request=None, responses=SessionSerializer)
    def post(self, request: Request, pk: int, action: str) -> Response:
        session = session_for(request, pk, Role.OPERATOR)
        to, allowed = ACTIONS[action]
        session = sessions.change_state(session, to, allowed)
        return Response(_document(session_for(request, session.pk)))


class SessionPublish(APIView):
    """Admins: a finished session's map becomes a sub-map, or a new version of the one it
    updated (409 when that one moved past the version the session started on)."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={201: VersionSerializer})
    def post(self, request: Request, pk: int) -> Response:
        session = session_for(request, pk, Role.ADMIN)
        note = request.data.get("note", "") if isinstance(request.data, dict) else ""
        made = sessions.publish(session, request.user, str(note))
        return Response(VersionSerializer(made).data, status=status.HTTP_201_CREATED)


# Proposed changes (map upkeep)


class ProposalSerializer(serializers.ModelSerializer[ChangeProposal]):
    decided_by: serializers.SlugRelatedField[Any] = serializers.SlugRelatedField(
        slug_field="username", read_only=True
    )

    class Meta:
        model = ChangeProposal
        fields = [
            "id",
            "based_on",
            "state",
            "added",
            "removed",
            "added_passes",
            "removed_passes",
            "added_robots",
            "removed_robots",
            "unknown",
            "edited",
            "passes",
            "robots",
            "scans",
            "created",
            "updated",
            "decided_by",
            "version",
        ]


class ProposalList(APIView):
    """The changes the fleet's lasers propose for a sub-map (``?state=open``), cells as
    ``[row, col]`` of the version they were seen on, with the passes and the robots
    backing each."""

    @extend_schema(
        parameters=[OpenApiParameter("state", str)], responses=ProposalSerializer(many=True)
    )
    def get(self, request: Request, building: str, map: str) -> Response:
        found = upkeep.proposals_of(building_for(request, building), map)
        if state := request.query_params.get("state"):
            found = found.filter(state=state)
        return Response(ProposalSerializer(found[:20], many=True).data)


MAX_EDITED_CELLS = 200_000


def _cell_list(help_text: str) -> serializers.ListField:
    pair = serializers.ListField(child=serializers.IntegerField(), min_length=2, max_length=2)
    return serializers.ListField(
        child=pair, max_length=MAX_EDITED_CELLS, default=list, help_text=help_text
    )


class CellEditSerializer(serializers.Serializer[Any]):
    """An admin's edit of a proposal: every cell it changes, as ``[row, col]`` of the
    version it was made on (``context["shape"]`` = that version's (height, width))."""

    added = _cell_list("cells that become occupied")
    removed = _cell_list("cells that become free")
    unknown = _cell_list("cells that become unknown")

    def validate(self, attrs: dict[str, Any]) -> dict[str, Any]:
        height, width = self.context["shape"]
        errors: dict[str, list[str]] = {}
        owner: dict[tuple[int, int], str] = {}
        for key in ("added", "removed", "unknown"):
            for row, col in attrs[key]:
                if not (0 <= row < height and 0 <= col < width):
                    errors.setdefault(key, []).append(
                        f"[{row}, {col}] is outside the map ({height} rows, {width} columns)."
                    )
                elif (row, col) in owner:
                    errors.setdefault(key, []).append(
                        f"[{row}, {col}] is also in {owner[row, col]}: a cell takes one value."
                    )
                owner.setdefault((row, col), key)
        if errors:
            raise serializers.ValidationError({k: v[:5] for k, v in errors.items()})
        return attrs


class ProposalDetail(APIView):
    """One proposal; admins ``PUT`` its cells as they edited them (``{"added", "removed",
    "unknown"}``: every cell the change sets, as ``[row, col]``), replacing the fleet's."""

    parser_classes = [JSONParser]

    def _proposal(self, request: Request, building: str, map: str, pk: int, need: Role) -> Any:
        proposal = upkeep.proposals_of(building_for(request, building, need), map)
        found = proposal.select_related("submap").filter(pk=pk).first()
        if found is None:
            raise NotFound("No such proposal.")
        return found

    @extend_schema(responses=ProposalSerializer)
    def get(self, request: Request, building: str, map: str, pk: int) -> Response:
        proposal = self._proposal(request, building, map, pk, Role.VIEWER)
        return Response(ProposalSerializer(proposal).data)

    @extend_schema(request=CellEditSerializer, responses=ProposalSerializer)
    def put(self, request: Request, building: str, map: str, pk: int) -> Response:
        proposal = self._proposal(request, building, map, pk, Role.ADMIN)
        version = versions.version_of(proposal.submap, proposal.based_on)
        asked = CellEditSerializer(
            data=request.data, context={"shape": (version.height, version.width)}
        )
        asked.is_valid(raise_exception=True)
        cells = asked.validated_data
        edited = upkeep.edit(proposal, cells["added"], cells["removed"], cells["unknown"])
        return Response(ProposalSerializer(edited).data)


class ProposalDecision(APIView):
    """Admins: ``accept`` a proposal (optionally only the cells kept: ``{"added": [...],
    "removed": [...]}``), making the next version, or ``reject`` it."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses=ProposalSerializer)
    def post(self, request: Request, building: str, map: str, pk: int, decision: str) -> Response:
        target = building_for(request, building, Role.ADMIN)
        proposal = upkeep.proposals_of(target, map).filter(pk=pk).first()
        if proposal is None:
            raise NotFound("No such proposal.")
        body = request.data if isinstance(request.data, dict) else {}
        if decision == "accept":
            upkeep.accept(proposal, request.user, _cells(body, "added"), _cells(body, "removed"))
        else:
            upkeep.reject(proposal, request.user)
        proposal.refresh_from_db()
        return Response(ProposalSerializer(proposal).data)


def _cells(body: dict[str, Any], key: str) -> list[list[int]] | None:
    value = body.get(key)
    if value is None:
        return None
    pair = serializers.ListField(child=serializers.IntegerField(), min_length=2, max_length=2)
    cells: list[list[int]] = serializers.ListField(child=pair).run_validation(value)
    return cells
