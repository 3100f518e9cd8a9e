"""A map file's image and its grid (a ``nav_msgs/OccupancyGrid`` under the heavy-work
budget) as responses: a sub-map's current map, or one of its versions."""

from __future__ import annotations

from django.http import HttpResponse, HttpResponseBase
from django.utils.http import content_disposition_header, quote_etag
from rest_framework.request import Request

from cloudnav_django.heavy import heavy_response

from .. import services
from ..domain.mapfile import occupancy_grid_json
from ..models import MapFile


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


def grid_response(request: Request, map_file: MapFile, frame_id: str) -> HttpResponseBase:
    """``map_file``'s grid as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON, under the
    heavy-work budget."""

    def build() -> bytes:
        meta = services.metadata_of(map_file)
        return occupancy_grid_json(services.grid_of(map_file), meta, frame_id=frame_id)

    need = map_file.width * map_file.height * GRID_BYTES_PER_CELL
    return heavy_response(request, need, build, "application/json")
