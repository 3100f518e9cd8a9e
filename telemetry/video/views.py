"""HTTP views of the video relays, at web_video_server's URLs.

- ``/stream?topic=T&type=mjpeg|vp8|ros_compressed`` (``quality``, ``width``, ``height``,
  ``invert``; ``bitrate``, ``qmin``, ``qmax``, ``gop`` for VP8): an endless stream;
- ``/snapshot?topic=T``: one JPEG;
- ``/stream_viewer?topic=T&type=...``: a page showing one stream;
- ``/whep?topic=T`` (``type=vp8|h264``, ``bitrate``, ``width``, ``height``, ``fps``):
  WebRTC by WHEP, POST an ``application/sdp`` offer, get ``201`` with the answer and a
  ``Location`` to DELETE when done (``telemetry.video.webrtc``);
- ``/video/``: the cameras the user may watch, with links to all of the above;
- ``/api/video/stats``: the figures of every stream the user may watch (JSON); with a
  stream's own query (``?topic=T&type=vp8...``, or ``type=source`` for the camera as
  published) only that stream's, so a player shows the figures of what it plays.

Views parse, authorise (``cameras``) and hand over to ``streams``; every video error maps
to its HTTP status in ``error_response`` only.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any
from urllib.parse import urlencode

from asgiref.sync import sync_to_async
from channels.db import database_sync_to_async
from django.conf import settings
from django.contrib.auth.views import redirect_to_login
from django.http import (
    HttpRequest,
    HttpResponse,
    HttpResponseBase,
    HttpResponseNotAllowed,
    JsonResponse,
    StreamingHttpResponse,
)
from django.middleware.csrf import CsrfViewMiddleware, get_token
from django.shortcuts import render
from django.urls import reverse
from django.views.decorators.csrf import csrf_exempt
from django.views.decorators.http import require_GET

from cloudnav_django.heavy import Overloaded, release_with
from maps.access import global_role
from maps.page_context import page_context
from telemetry.access.decisions import owner_named
from telemetry.access.rules import Principal, may_watch
from telemetry.domain import multipart, names
from telemetry.domain.video import (
    MJPEG,
    SOURCE,
    VP8,
    BadFrame,
    BadStreamParam,
    NoFrame,
    NotAuthenticated,
    NotWatchable,
    StreamParams,
    StreamRequest,
    UnknownStream,
    VideoError,
    camera_topic_candidates,
    parse_stream_request,
)
from telemetry.domain.webrtc import MIME_TYPES, parse_whep_request
from telemetry.video.cameras import (
    Camera,
    CameraListing,
    find_camera,
    principal_of,
    token_of,
    watchable_cameras,
)
from telemetry.video.relay import VideoRelay, get_video_relay
from telemetry.video.streams import image_body, snapshot, webm_body
from telemetry.video.webrtc import OfferRefused, TooManySessions, sessions_of

WEBM = "video/webm"
WEBRTC = "webrtc"  # the viewer page's name of the /whep stream
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
    request: HttpRequest, parse: Callable[[Mapping[str, str]], StreamRequest] = parse_stream_request
) -> tuple[VideoRelay, Camera, StreamRequest, Principal]:
    """Return the relay, the camera and the stream a request asks for, and who asks.

    Raises VideoError."""
    principal = await principal_of(request)
    asked = parse(request.GET)
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


MAX_OFFER_BYTES = 64 * 1024
SDP = "application/sdp"


@csrf_exempt  # checked below for sessions; a robot's token cannot be sent by another site
async def whep(request: HttpRequest) -> HttpResponseBase:
    """WHEP: answer an SDP offer with a peer sending the camera (201, the answer, and the
    session's ``Location``); 415 for another content type, 429 beyond the client's share of
    sessions or encoders, 400 for an offer that cannot be answered."""
    if request.method != "POST":
        return HttpResponseNotAllowed(["POST"])
    try:
        relay, camera, asked, principal = await _requested(request, parse_whep_request)
    except VideoError as error:
        return error_response(error)
    refused = _offer_refusal(request)
    if refused is not None:
        return refused
    try:
        ticket = relay.reserve(camera.topic, asked.params, principal.label)
        offer = request.body.decode("utf-8")
        session, answer = await sessions_of(relay).open(
            camera, asked.params, principal, offer, ticket
        )
    except Overloaded as busy:
        return busy_response(busy)
    except TooManySessions as error:
        return HttpResponse(f"{error}\n", status=429, content_type="text/plain")
    except (OfferRefused, UnicodeDecodeError) as error:
        return HttpResponse(f"{error}\n", status=400, content_type="text/plain")
    response = HttpResponse(answer, status=201, content_type=SDP)
    response["Location"] = reverse("video-whep-session", args=[session.id])
    for link in ice_server_links(settings.CLOUDNAV_WEBRTC_ICE_SERVERS):
        response.headers.setdefault("Link", link)  # WHEP's way of telling the ICE servers
    return response


@csrf_exempt
async def whep_session(request: HttpRequest, session: str) -> HttpResponseBase:
    """End a WebRTC session (DELETE by whoever opened it): 200, or 404 if there is none."""
    if request.method != "DELETE":
        return HttpResponseNotAllowed(["DELETE"])
    refused = _csrf_refusal(request)
    if refused is not None:
        return refused
    try:
        principal = await principal_of(request)
    except VideoError as error:
        return error_response(error)
    relay = await get_video_relay()
    if not await sessions_of(relay).close(session, principal.label):
        return HttpResponse("no such session\n", status=404, content_type="text/plain")
    return HttpResponse(status=200)


def _offer_refusal(request: HttpRequest) -> HttpResponse | None:
    """403 without the CSRF token a session needs, 415 and 413 for what is no offer."""
    refused = _csrf_refusal(request)
    if refused is not None:
        return refused
    if request.content_type != SDP:
        return HttpResponse(f"the offer must be {SDP}\n", status=415, content_type="text/plain")
    if len(request.body) > MAX_OFFER_BYTES:
        return HttpResponse("the offer is too large\n", status=413, content_type="text/plain")
    return None


def _csrf_refusal(request: HttpRequest) -> HttpResponse | None:
    """Django's CSRF check for requests that rely on the session (as DRF does it)."""
    if token_of(request) is not None:
        return None
    check = CsrfViewMiddleware(lambda _r: HttpResponse())
    refusal: HttpResponse | None = check.process_view(request, _no_view, (), {})
    return refusal


def _no_view(_request: HttpRequest) -> HttpResponse:  # process_view needs one; never called
    return HttpResponse()


def ice_server_links(servers: list[dict[str, Any]]) -> list[str]:
    """The ``Link`` header values that tell a WHEP client the ICE servers (RFC 9725)."""
    links = []
    for server in servers:
        urls = server["urls"] if isinstance(server["urls"], list) else [server["urls"]]
        for url in urls:
            link = f'<{url}>; rel="ice-server"'
            if "username" in server:
                link += f'; username="{server["username"]}"; credential="{server["credential"]}"'
                link += '; credential-type="password"'
            links.append(link)
    return links


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
        _, camera, asked, _ = await _requested(request, _viewer_request)
    except NotAuthenticated as error:
        if token_of(request) is None:
            return redirect_to_login(request.get_full_path())
        return error_response(error)
    except VideoError as error:
        return error_response(error)
    query = request.META.get("QUERY_STRING", "")
    get_token(request)  # the CSRF cookie the WebRTC player's POST to /whep sends back
    context = {
        "topic": camera.topic,
        "robot": camera.robot,
        "type": asked.params.type,
        "params": asked.params.label(),
        "stream_url": f"{reverse('video-stream')}?{query}",
        "snapshot_url": f"{reverse('video-snapshot')}?{query}",
        "webm": asked.params.type == VP8,
        "webrtc": asked.params.type in MIME_TYPES,
        "whep_url": f"{reverse('video-whep')}?{urlencode(_whep_query(request.GET))}",
        "fallback_url": f"{reverse('video-stream')}?topic={camera.topic}&type={MJPEG}",
        "query": request.GET.dict(),  # the stream's figures are asked with its own query
    }
    return await sync_to_async(render)(request, "telemetry/stream_viewer.html", context)


def _viewer_request(query: Mapping[str, str]) -> StreamRequest:
    """The viewer page's stream: ``/stream``'s types, and ``type=webrtc`` (with ``/whep``'s
    parameters, the codec as ``codec=vp8|h264``)."""
    if query.get("type") == WEBRTC:
        return parse_whep_request(_whep_query(query))
    return parse_stream_request(query)


def _whep_query(query: Mapping[str, str]) -> dict[str, str]:
    """The ``/whep`` query of a viewer page's ``type=webrtc&codec=...`` query."""
    whep = {k: v for k, v in query.items() if k not in ("type", "codec")}
    return whep | {"type": query.get("codec", "vp8")}


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
    context["viewer_types"] = [WEBRTC, MJPEG, VP8]
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
    params = _stats_params(query)
    return [
        e
        for e in entries
        if e["topic"] in topics and e["type"] == params.type and e["params"] == params.label()
    ]


def _stats_params(query: Mapping[str, str]) -> StreamParams:
    """The params of the stream a statistics query names: ``type=webrtc/vp8`` (or h264)
    with ``/whep``'s parameters, else ``/stream``'s."""
    kind = query.get("type", "")
    if kind in MIME_TYPES:
        return parse_whep_request({**query, "type": kind.split("/")[1]}).params
    return _viewer_request(query).params


def _watchable(principal: Principal, topics: set[str]) -> set[str]:
    owners = {robot: owner_named(robot) for robot in {names.first_segment(t) for t in topics}}
    return {t for t in topics if may_watch(principal, owners[names.first_segment(t)])}
