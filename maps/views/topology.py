"""A building's topology: the graph of its sub-maps, its validation against the tags, and routes."""

from __future__ import annotations

from typing import Any

from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework.exceptions import ValidationError
from rest_framework.parsers import JSONParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from .. import services
from ..access import Role
from ..domain.topology import Coverage, Edge
from ..models import Building
from ..serializers import CoverageSerializer, RouteSerializer, TagSerializer, TopologySerializer
from .lookups import building_for


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
