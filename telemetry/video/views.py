"""HTTP views of the video relays, at web_video_server's URLs.

- ``/stream?topic=T&type=mjpeg|vp8|ros_compressed`` (``quality``, ``width``, ``height``,
  ``invert``; ``bitrate``, ``qmin``, ``qmax``, ``gop`` for VP8): an endless stream;
- ``/snapshot?topic=T``: one JPEG;
- ``/stream_viewer?topic=T&type=...``: a page showing one stream;
- ``/video/``: the cameras the user may watch, with links to all of the above;
- ``/api/video/stats``: the figures of every stream the user may watch (JSON); with a
  stream's own query (``?topic=T&type=vp8...``, or ``type=source`` for the camera as
  published) only that stream's, so a player shows the figures of what it plays.

Views parse, authorise (``cameras``) and hand over to ``streams``; every video error maps
to its HTTP status in ``error_response`` only.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from asgiref.sync import sync_to_async
from channels.db import database_sync_to_async
from django.contrib.auth.views import redirect_to_login
from django.http import (
    HttpRequest,
    HttpResponse,
    HttpResponseBase,
    JsonResponse,
    StreamingHttpResponse,
)
from django.shortcuts import render
from django.urls import reverse
from django.views.decorators.http import require_GET

from cloudnav_web.heavy import Overloaded, release_with
from cloudnav_web.pages import _context as page_context
from maps.access import global_role
from telemetry.domain import multipart, names
from telemetry.domain.rules import Principal
from telemetry.domain.video import (
    MJPEG,
    SOURCE,
    VP8,
    BadFrame,
    BadStreamParam,
    NoFrame,
    NotAuthenticated,
    NotWatchable,
    StreamRequest,
    UnknownStream,
    VideoError,
    camera_topic_candidates,
    parse_stream_request,
)
from telemetry.services import owner_named
from telemetry.video.cameras import (
    Camera,
    CameraListing,
    find_camera,
    may_watch,
    principal_of,
    token_of,
    watchable_cameras,
)
from telemetry.video.relay import VideoRelay, get_video_relay
from telemetry.video.streams import image_body, snapshot, webm_body

WEBM = "video/webm"
ERROR_STATUS: dict[type[VideoError], int] = {
    NotAuthenticated: 401,
    BadStreamParam: 400,
    UnknownStream: 404,
    NotWatchable: 403,
    NoFrame: 503,
    BadFrame: 502,
}


def error_response(error: VideoError, as_json: bool = False) -> HttpResponse:
    """Return the answer to ``error``: its status, and the reason as text (or JSON)."""
    status = next(code for kind, code in ERROR_STATUS.items() if isinstance(error, kind))
    if as_json:
        response: HttpResponse = JsonResponse({"detail": str(error)}, status=status)
    else:
        response = HttpResponse(f"{error}\n", status=status, content_type="text/plain")
    if status == 401:
        response["WWW-Authenticate"] = "Token"
    return response


async def _requested(
    request: HttpRequest,
) -> tuple[VideoRelay, Camera, StreamRequest, Principal]:
    """Return the relay, the camera and the stream a request asks for, and who asks.

    Raises VideoError."""
    principal = await principal_of(request)
    asked = parse_stream_request(request.GET)
    relay = await get_video_relay()
    camera = await find_camera(relay.hub, asked.topic, principal)
    return relay, camera, asked, principal


@require_GET
async def stream(request: HttpRequest) -> HttpResponseBase:
    """An endless stream; a new encoder first takes its share of the video budget (429 or
    503 with Retry-After when there is none)."""
    try:
        relay, camera, asked, principal = await _requested(request)
    except VideoError as error:
        return error_response(error)
    try:
        ticket = relay.reserve(camera.topic, asked.params, principal.label)
    except Overloaded as busy:
        return busy_response(busy)
    scope = getattr(request, "scope", {})
    response: StreamingHttpResponse
    if asked.params.type == VP8:
        body = webm_body(relay, camera, asked.params, scope, ticket, principal)
        response = StreamingHttpResponse(body, headers=multipart.video_headers(WEBM))
    else:
        body = image_body(relay, camera, asked.params, scope, ticket, principal)
        response = StreamingHttpResponse(body, headers=multipart.stream_headers())
    if ticket is not None:
        release_with(response, ticket)  # if the body never starts; the encoder takes it over
    return response


def busy_response(busy: Overloaded) -> HttpResponse:
    response = HttpResponse(f"{busy.detail}\n", status=busy.status_code, content_type="text/plain")
    if busy.wait is not None:
        response["Retry-After"] = str(busy.wait)
    return response


@require_GET
async def snapshot_view(request: HttpRequest) -> HttpResponse:
    try:
        relay, camera, asked, _ = await _requested(request)
        part = await snapshot(relay, camera, asked.params)
    except VideoError as error:
        return error_response(error)
    headers = multipart.snapshot_headers(
        part.content_type, part.frame.origin_time, len(part.payload)
    )
    return HttpResponse(part.payload, headers=headers)


@require_GET
async def stream_viewer(request: HttpRequest) -> HttpResponse:
    """A page with one stream, as web_video_server's viewer (VP8 through Media Source
    Extensions, which Chromium plays live where a plain ``<video>`` lags)."""
    try:
        _, camera, asked, _ = await _requested(request)
    except NotAuthenticated as error:
        if token_of(request) is None:
            return redirect_to_login(request.get_full_path())
        return error_response(error)
    except VideoError as error:
        return error_response(error)
    query = request.META.get("QUERY_STRING", "")
    context = {
        "topic": camera.topic,
        "robot": camera.robot,
        "type": asked.params.type,
        "params": asked.params.label(),
        "stream_url": f"{reverse('video-stream')}?{query}",
        "snapshot_url": f"{reverse('video-snapshot')}?{query}",
        "webm": asked.params.type == VP8,
        "query": request.GET.dict(),  # the stream's figures are asked with its own query
    }
    return await sync_to_async(render)(request, "telemetry/stream_viewer.html", context)


@require_GET
async def camera_topics(request: HttpRequest) -> HttpResponse:
    """The cameras the user may watch, each with its viewers, stream and snapshot."""
    try:
        principal = await principal_of(request)
    except NotAuthenticated:
        return redirect_to_login(request.get_full_path())
    relay = await get_video_relay()
    cameras = await watchable_cameras(relay.hub, principal)
    return await sync_to_async(_render_topics)(request, cameras)


def _render_topics(request: HttpRequest, cameras: list[CameraListing]) -> HttpResponse:
    context = page_context(request, global_role(request.user), page="video", cameras=cameras)
    context["stream_types"] = [MJPEG, VP8]
    return render(request, "telemetry/camera_topics.html", context)


@require_GET
async def video_stats(request: HttpRequest) -> HttpResponse:
    """``{"streams": [...]}``: each stream's figures, then each camera feed's, for the
    cameras the asker may watch (see ``VideoRelay.stats``); only those of the stream a
    ``/stream`` query names when given one."""
    try:
        principal = await principal_of(request)
        relay = await get_video_relay()
        entries = _asked_for(relay.stats(), request.GET)
    except (NotAuthenticated, BadStreamParam, UnknownStream) as error:
        return error_response(error, as_json=True)
    allowed = await database_sync_to_async(_watchable)(principal, {e["topic"] for e in entries})
    return JsonResponse({"streams": [e for e in entries if e["topic"] in allowed]})


def _asked_for(entries: list[dict[str, Any]], query: Mapping[str, str]) -> list[dict[str, Any]]:
    """The entries of the stream ``query`` names as ``/stream`` would read it (all of them
    without a ``topic``; the camera as published for ``type=source``). Raises
    UnknownStream or BadStreamParam as ``/stream`` does."""
    if "topic" not in query:
        return entries
    topics = camera_topic_candidates(query["topic"])
    if query.get("type") == SOURCE:
        return [e for e in entries if e["topic"] in topics and e["type"] == SOURCE]
    params = parse_stream_request(query).params
    return [
        e
        for e in entries
        if e["topic"] in topics and e["type"] == params.type and e["params"] == params.label()
    ]


def _watchable(principal: Principal, topics: set[str]) -> set[str]:
    owners = {robot: owner_named(robot) for robot in {names.first_segment(t) for t in topics}}
    return {t for t in topics if may_watch(principal, owners[names.first_segment(t)])}
