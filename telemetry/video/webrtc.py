"""WebRTC video by WHEP: one encoder per camera and parameter set, one peer per viewer.

``RtcPipeline`` (``telemetry.video.pipelines``) encodes the camera's newest frame once
(VP8 or H.264, in the relay's encoding threads) and keeps the newest packet; each
viewer's ``PacketTrack`` hands the packets to aiortc, which sends an ``av.Packet`` as it
is (no re-encoding per viewer). A viewer that falls behind skips to the newest packet,
then waits for the next keyframe (and asks the encoder for one, at most once a second),
so it loses frames and nobody else does. The pipeline stops with its last viewer, as
every relay pipeline does.

``WhepSessions`` holds this process's peer connections by their resource id (the
``Location`` a viewer DELETEs). A viewer that vanishes without a DELETE is dropped when
ICE consent freshness (RFC 7675) fails: aioice checks consent every ``CONSENT_INTERVAL``
seconds and gives up after ``CONSENT_FAILURES`` misses, which we shorten from its 5 s x 6
to 1 s x 3, so a vanished browser frees its encoder share within about 4 s. A peer that
never connects is dropped after ``connect_timeout`` (``CLOUDNAV_WHEP_CONNECT_TIMEOUT``),
with its encoder.
"""

from __future__ import annotations

import asyncio
import logging
import secrets
import time
import weakref
from collections import OrderedDict
from contextlib import AsyncExitStack
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import aioice.ice
import av
from aiortc import (
    RTCConfiguration,
    RTCIceServer,
    RTCPeerConnection,
    RTCRtpSender,
    RTCSessionDescription,
)
from aiortc.exceptions import InvalidAccessError, InvalidStateError, OperationError
from aiortc.mediastreams import MediaStreamError, MediaStreamTrack
from django.conf import settings

from telemetry.domain.newest import Closed
from telemetry.domain.video import StreamParams
from telemetry.domain.webrtc import MIME_TYPES
from telemetry.video.pipelines import RtcPipeline

if TYPE_CHECKING:
    from cloudnav_django.heavy import Ticket
    from telemetry.access.rules import Principal
    from telemetry.video.cameras import Camera
from telemetry.video.relay import VideoRelay

logger = logging.getLogger(__name__)

aioice.ice.CONSENT_INTERVAL = 1  # module constants of aioice
aioice.ice.CONSENT_FAILURES = 3
ENDED_KEPT = 256


class OfferRefused(Exception):
    """The SDP offer cannot be answered (malformed, or it takes no video)."""


class TooManySessions(Exception):
    """The client holds as many WebRTC sessions as it may."""


class PacketTrack(MediaStreamTrack):
    """A viewer's video track: the pipeline's packets, from a keyframe on."""

    kind = "video"

    def __init__(self, pipeline: RtcPipeline) -> None:
        super().__init__()
        self.pipeline = pipeline
        self.version = pipeline.output.version
        self.skipped = 0
        self._need_keyframe = True
        pipeline.ask_keyframe()  # so a new viewer starts at once, not at the next interval

    async def recv(self) -> av.Packet[Any]:  # aiortc sends Packets as they are
        """Return the next packet to send. Raises MediaStreamError once the stream ends."""
        while True:
            try:
                version, packet = await self.pipeline.output.newer(self.version)
            except Closed:
                self.stop()
                raise MediaStreamError from None
            if version > self.version + 1 and not self._need_keyframe:
                self.skipped += version - self.version - 1
                self._need_keyframe = True
                self.pipeline.ask_keyframe()
            self.version = version
            if packet.is_keyframe:
                self._need_keyframe = False
            if not self._need_keyframe:
                return packet
            # Still waiting: the keyframe asked for may have gone out before this viewer
            # read (its connection was still being set up). Without asking again it would
            # wait for the encoder's interval: 60 frames, 12 s of a 5 frames/s camera.
            self.pipeline.ask_keyframe()


@dataclass
class WhepSession:
    """One viewer's peer connection and what it holds of the relay."""

    id: str
    client: str
    topic: str
    params: StreamParams
    peer: RTCPeerConnection
    track: PacketTrack | None = None
    started: float = field(default_factory=time.time)
    resources: AsyncExitStack = field(default_factory=AsyncExitStack)


def ice_configuration(servers: list[dict[str, Any]]) -> RTCConfiguration:
    """Return aiortc's configuration for the settings' ICE servers (none: host candidates
    only, which is all a peer on this machine or its LAN needs)."""
    return RTCConfiguration(
        iceServers=[
            RTCIceServer(s["urls"], s.get("username"), s.get("credential")) for s in servers
        ]
    )


class WhepSessions:
    """This process's WebRTC sessions, at most ``per_client`` for each client."""

    def __init__(
        self,
        relay: VideoRelay,
        ice_servers: list[dict[str, Any]],
        per_client: int,
        connect_timeout: float,
    ):
        self.relay = relay
        self.ice_servers = ice_servers
        self.per_client = per_client
        self.connect_timeout = connect_timeout
        self.sessions: dict[str, WhepSession] = {}
        # Sessions that ended on their own (the peer failed or left, access revoked), by id,
        # with their client: its DELETE, which may come after (a page changing mode), is
        # answered as done, not 404. The newest ENDED_KEPT only.
        self.ended: OrderedDict[str, str] = OrderedDict()

    def count(self, client: str) -> int:
        return sum(1 for s in self.sessions.values() if s.client == client)

    async def open(
        self,
        camera: Camera,
        params: StreamParams,
        principal: Principal,
        offer: str,
        ticket: Ticket | None,
    ) -> tuple[WhepSession, str]:
        """Answer ``offer`` with a peer sending the stream ``params`` of ``camera``; return
        the session and the SDP answer (all candidates gathered: WHEP without trickle). The
        session ends by itself when the principal's access to the camera is revoked.

        Raises TooManySessions, OfferRefused, RosbridgeError (TypeConflict) as the relay."""
        topic, client = camera.topic, principal.label
        if self.count(client) >= self.per_client:
            if ticket is not None:
                ticket.release()
            raise TooManySessions(f"{client} has {self.per_client} WebRTC sessions open")
        peer = RTCPeerConnection(ice_configuration(self.ice_servers))
        session = WhepSession(secrets.token_urlsafe(18), client, topic, params, peer)
        self.sessions[session.id] = session
        try:
            ended = session.resources.enter_context(
                self.relay.hub.review.watching(principal, camera.robot, camera.robot_pk)
            )
            self._end_when(session, ended)
            pipeline = await session.resources.enter_async_context(
                self.relay.watch(topic, params, ticket)
            )
            assert isinstance(pipeline, RtcPipeline)  # the relay's pipeline of a WebRTC type
            session.track = PacketTrack(pipeline)
            answer = await self._answer(session, offer)
        except BaseException:
            await self.close(session.id)
            raise
        self._watch_state(session)
        return session, answer

    async def _answer(self, session: WhepSession, offer: str) -> str:
        peer = session.peer
        assert session.track is not None
        # Added before the offer is applied, the transceiver takes its first video m-line
        # with only our codec (and its retransmissions) left to negotiate.
        sending = peer.addTransceiver(session.track, direction="sendonly")
        mime = MIME_TYPES[session.params.type]
        codecs = RTCRtpSender.getCapabilities("video").codecs
        sending.setCodecPreferences([c for c in codecs if c.mimeType in (mime, "video/rtx")])
        try:
            await peer.setRemoteDescription(RTCSessionDescription(offer, "offer"))
            await peer.setLocalDescription(await peer.createAnswer())
        except (ValueError, AssertionError, InvalidAccessError, InvalidStateError) as error:
            raise OfferRefused(f"the offer is not usable SDP: {error}") from None
        except OperationError:
            raise OfferRefused(f"the offer takes no video in {mime}") from None
        if sending.mid is None:
            raise OfferRefused("the offer has no video m-line")
        return peer.localDescription.sdp

    def _end_when(self, session: WhepSession, ended: asyncio.Event) -> None:
        """Close ``session`` once ``ended`` is set (its access was revoked)."""

        async def _revoked() -> None:
            await ended.wait()
            await self.close(session.id)

        session.resources.push_async_callback(_cancel, asyncio.create_task(_revoked()))

    def _watch_state(self, session: WhepSession) -> None:
        @session.peer.on("connectionstatechange")
        async def _changed() -> None:
            if session.peer.connectionState in ("failed", "closed"):
                await self.close(session.id)

        async def _connect_or_drop() -> None:
            await asyncio.sleep(self.connect_timeout)
            if session.peer.connectionState != "connected":
                await self.close(session.id)

        session.resources.push_async_callback(_cancel, asyncio.create_task(_connect_or_drop()))

    async def close(self, session_id: str, client: str | None = None) -> bool:
        """End a session: ``client``'s (a DELETE), or any (``client`` None: it ended on its
        own). False if there is none; True for ``client``'s that ended on its own."""
        session = self.sessions.get(session_id)
        if session is None and client is not None:
            if self.ended.get(session_id) != client:
                return False
            del self.ended[session_id]
            return True
        if session is None or (client is not None and session.client != client):
            return False
        del self.sessions[session_id]
        if client is None:
            self.ended[session_id] = session.client
            while len(self.ended) > ENDED_KEPT:
                self.ended.popitem(last=False)
        if session.track is not None:
            session.track.stop()
        await session.peer.close()
        await session.resources.aclose()
        return True

    def stats(self) -> list[dict[str, Any]]:
        """One entry per session: who, what, since when, frames skipped."""
        return [
            {
                "id": s.id[:6],
                "client": s.client,
                "topic": s.topic,
                "params": s.params.label(),
                "state": s.peer.connectionState,
                "skipped": s.track.skipped if s.track else 0,
                "started": s.started,
            }
            for s in self.sessions.values()
        ]


async def _cancel(task: asyncio.Task[None]) -> None:
    if task is not asyncio.current_task():
        task.cancel()


_sessions: weakref.WeakKeyDictionary[VideoRelay, WhepSessions] = weakref.WeakKeyDictionary()


def sessions_of(relay: VideoRelay) -> WhepSessions:
    """Return the WebRTC sessions of ``relay`` (its event loop's), creating them first."""
    found = _sessions.get(relay)
    if found is None:
        found = WhepSessions(
            relay,
            settings.CLOUDNAV_WEBRTC_ICE_SERVERS,
            settings.CLOUDNAV_WHEP_PER_CLIENT,
            settings.CLOUDNAV_WHEP_CONNECT_TIMEOUT,
        )
        _sessions[relay] = found
    return found
