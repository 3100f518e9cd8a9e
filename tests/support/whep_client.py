"""A WHEP viewer (the client side, for tests and benchmarks): aiortc receiving a camera.

``WhepViewer.open`` POSTs a receive-only offer to ``/whep?...`` (all candidates gathered,
as WHEP without trickle), applies the answer and keeps the ``Location``; ``frames`` yields
the decoded pictures; ``close`` DELETEs the session and closes the peer.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urljoin

import httpx
from aiortc import RTCPeerConnection, RTCSessionDescription
from aiortc.mediastreams import MediaStreamError, MediaStreamTrack
from av.video.frame import VideoFrame

SDP = "application/sdp"


class WhepRefused(Exception):
    """The server did not answer the offer with 201; ``status`` and ``body`` say why."""

    def __init__(self, status: int, body: str) -> None:
        super().__init__(f"{status}: {body.strip()}")
        self.status = status
        self.body = body


@dataclass
class WhepViewer:
    """One WebRTC session with the server: the peer, its video track, the resource URL."""

    base_url: str
    headers: dict[str, str]
    peer: RTCPeerConnection
    location: str = ""
    answer: str = ""
    track: asyncio.Future[MediaStreamTrack] = field(
        default_factory=lambda: asyncio.get_running_loop().create_future()
    )

    @classmethod
    async def open(cls, base_url: str, query: str, headers: dict[str, str]) -> WhepViewer:
        """Open a session for ``/whep?{query}``. Raises WhepRefused (then nothing is left)."""
        viewer = cls(base_url, headers, RTCPeerConnection())
        viewer.peer.addTransceiver("video", direction="recvonly")

        @viewer.peer.on("track")
        def _track(track: MediaStreamTrack) -> None:
            if not viewer.track.done():
                viewer.track.set_result(track)

        await viewer.peer.setLocalDescription(await viewer.peer.createOffer())
        try:
            await viewer._exchange(query)
        except BaseException:
            await viewer.peer.close()
            raise
        return viewer

    async def _exchange(self, query: str) -> None:
        async with httpx.AsyncClient(base_url=self.base_url, timeout=30) as http:
            answer = await http.post(
                f"/whep?{query}",
                content=self.peer.localDescription.sdp,
                headers={**self.headers, "Content-Type": SDP},
            )
        if answer.status_code != 201:
            raise WhepRefused(answer.status_code, answer.text)
        self.answer = answer.text
        self.location = urljoin(self.base_url, answer.headers["location"])
        await self.peer.setRemoteDescription(RTCSessionDescription(answer.text, "answer"))

    async def frames(self, patience: float = 10.0) -> AsyncIterator[VideoFrame]:
        """Yield each decoded picture until the stream ends; TimeoutError if none comes
        for ``patience`` seconds."""
        track = await asyncio.wait_for(asyncio.shield(self.track), patience)
        while True:
            try:
                frame = await asyncio.wait_for(track.recv(), patience)
            except MediaStreamError:
                return
            assert isinstance(frame, VideoFrame)  # a video track gives video frames
            yield frame

    async def delete(self) -> int:
        """DELETE the session; return the status."""
        async with httpx.AsyncClient(timeout=30) as http:
            answer = await http.delete(self.location, headers=self.headers)
        return answer.status_code

    async def close(self) -> None:
        """End the session (DELETE, then close the peer)."""
        try:
            await self.delete()
        finally:
            await self.peer.close()

    def stats(self) -> dict[str, Any]:
        return {"location": self.location, "state": self.peer.connectionState}
