// A live `video/webm` stream (the VP8 relay) played through Media Source Extensions fed by
// fetch: Chromium starts it at once and keeps it live, where a plain <video src> on an
// endless WebM stalls and then lags. The robot page's camera panel and /stream_viewer
// both use it.
//
// Staying live without seeking: the relay declares each frame's duration and stamps frames
// with their arrival times, so the buffer's timeline runs at the camera's real pace and
// playing at 1x keeps a constant delay. When the player fell behind (it waited for data,
// or the tab was hidden) it plays a little faster until it is near the live edge again;
// only a player far behind seeks, because a seek into a VP8 stream decodes again from the
// last keyframe and shows nothing meanwhile.

const TYPE = 'video/webm; codecs="vp8"';
const NEAR_S = 0.6; // behind the buffer's end: live enough
const BEHIND_S = 1.5; // behind the buffer's end: catch up by playing faster
const CATCH_UP_RATE = 1.1;
const FAR_S = 5.0; // behind the buffer's end: jump to the live edge
const LIVE_EDGE_S = 0.3;
const KEEP_S = 10; // seconds of played video kept in the buffer

export function canPlayWebm() {
  return Boolean(window.MediaSource && MediaSource.isTypeSupported(TYPE));
}

export class LiveWebmPlayer {
  /** Play `url` in `video`; `onError(text)` is told why it cannot. */
  constructor(video, url, onError = () => {}) {
    this.video = video;
    this.abort = new AbortController();
    this.onError = onError;
    this.seeks = 0;
    if (!canPlayWebm()) {
      onError("This browser cannot play VP8 through Media Source Extensions.");
      return;
    }
    this.source = new MediaSource();
    video.src = URL.createObjectURL(this.source);
    this.source.addEventListener("sourceopen", () => this.#feed(url), { once: true });
  }

  /** Seconds between the playing position and the end of what is buffered. */
  get lag() {
    const buffered = this.buffer?.buffered;
    if (!buffered?.length) return Number.NaN;
    return buffered.end(buffered.length - 1) - this.video.currentTime;
  }

  async #feed(url) {
    const buffer = this.source.addSourceBuffer(TYPE);
    this.buffer = buffer;
    // Sequence mode lays frames end to end: a gap in the stream never leaves a hole in
    // the buffer that playback would stall at.
    buffer.mode = "sequence";
    try {
      const response = await fetch(url, { signal: this.abort.signal, credentials: "same-origin" });
      if (!response.ok || !response.body) throw new Error(`the VP8 relay answered ${response.status}`);
      const reader = response.body.getReader();
      for (;;) {
        const { value, done } = await reader.read();
        if (done) break;
        await append(buffer, value);
        this.#keepLive(buffer);
      }
    } catch (error) {
      if (error.name !== "AbortError") this.onError(`VP8 stream unavailable: ${error.message}`);
    }
  }

  #keepLive(buffer) {
    const video = this.video;
    const lag = this.lag;
    if (!Number.isFinite(lag)) return;
    if (lag > FAR_S) {
      this.seeks += 1;
      video.currentTime = video.currentTime + lag - LIVE_EDGE_S;
    } else if (lag > BEHIND_S) {
      video.playbackRate = CATCH_UP_RATE;
    } else if (lag < NEAR_S) {
      video.playbackRate = 1;
    }
    if (video.paused) video.play().catch(() => {});
    const start = buffer.buffered.start(0);
    if (video.currentTime - start > KEEP_S * 2 && !buffer.updating) buffer.remove(start, video.currentTime - KEEP_S);
  }

  stop() {
    this.abort.abort();
    if (this.source?.readyState === "open") {
      try {
        this.source.endOfStream();
      } catch {
        // The stream may already be ending; nothing to stop.
      }
    }
    this.video.removeAttribute("src");
  }
}

function append(buffer, chunk) {
  return new Promise((resolve, reject) => {
    const wait = () => {
      buffer.addEventListener("updateend", resolve, { once: true });
      buffer.addEventListener("error", reject, { once: true });
      buffer.appendBuffer(chunk);
    };
    if (buffer.updating) buffer.addEventListener("updateend", wait, { once: true });
    else wait();
  });
}

// ---------------------------------------------------------------- WebRTC (WHEP)
//
// A camera as a WebRTC stream: a receive-only offer POSTed to /whep (WHEP), the answer
// applied, the session DELETEd when the player stops. The server gathers its candidates
// before answering and so do we (no trickle), so one request sets the call up. The
// browser's jitter buffer is kept at its minimum: a teleoperation picture must be now.

const GATHER_MS = 2000; // candidates not gathered by then are left out
const FIRST_FRAME_MS = 8000; // no picture by then: WebRTC counts as failed here

function csrfToken() {
  const match = document.cookie.match(/(?:^|;\s*)csrftoken=([^;]+)/);
  return match ? decodeURIComponent(match[1]) : "";
}

export function canPlayWebRtc() {
  return typeof RTCPeerConnection === "function";
}

export class LiveRtcPlayer {
  /** Play `url` (`/whep?topic=...`) in `video`; `onError(text)` is told once if it fails. */
  constructor(video, url, onError = () => {}) {
    this.video = video;
    this.failed = false;
    this.onError = (text) => {
      if (this.failed || this.stopped) return;
      this.failed = true;
      onError(text);
    };
    this.previous = null; // the last getStats figures, for rates
    if (!canPlayWebRtc()) {
      this.onError("This browser has no WebRTC.");
      return;
    }
    this.peer = new RTCPeerConnection();
    this.#start(url).catch((error) => this.onError(`WebRTC unavailable: ${error.message}`));
  }

  async #start(url) {
    const peer = this.peer;
    const transceiver = peer.addTransceiver("video", { direction: "recvonly" });
    peer.addEventListener("track", (event) => {
      if ("jitterBufferTarget" in event.receiver) event.receiver.jitterBufferTarget = 0;
      this.video.srcObject = new MediaStream([event.track]);
      this.video.play().catch(() => {});
    });
    peer.addEventListener("connectionstatechange", () => {
      if (peer.connectionState === "failed") this.onError("WebRTC connection failed");
    });
    this.firstFrame = setTimeout(() => {
      if (!this.video.videoWidth) this.onError("WebRTC sent no picture");
    }, FIRST_FRAME_MS);
    await peer.setLocalDescription(await peer.createOffer());
    await gathered(peer);
    const response = await fetch(url, {
      method: "POST",
      credentials: "same-origin",
      headers: { "Content-Type": "application/sdp", "X-CSRFToken": csrfToken() },
      body: peer.localDescription.sdp,
    });
    if (response.status !== 201) throw new Error(`the server answered ${response.status}`);
    this.location = new URL(response.headers.get("Location"), window.location.href).href;
    if (this.stopped) return this.#delete();
    await peer.setRemoteDescription({ type: "answer", sdp: await response.text() });
    this.transceiver = transceiver;
  }

  /** The receiver's figures now: frames/s shown, kbit/s received, and the browser's own
   * share of the delay (jitter buffer and decoding), averaged since the last call. */
  async stats() {
    if (!this.peer) return null;
    const report = await this.peer.getStats();
    let inbound = null;
    report.forEach((entry) => {
      if (entry.type === "inbound-rtp" && entry.kind === "video") inbound = entry;
    });
    if (!inbound) return null;
    const last = this.previous || inbound;
    this.previous = inbound;
    const seconds = (inbound.timestamp - last.timestamp) / 1000 || 1;
    const emitted = inbound.jitterBufferEmittedCount - (last.jitterBufferEmittedCount || 0);
    const buffered = inbound.jitterBufferDelay - (last.jitterBufferDelay || 0);
    const decoded = inbound.framesDecoded - (last.framesDecoded || 0);
    const decoding = inbound.totalDecodeTime - (last.totalDecodeTime || 0);
    return {
      fps: inbound.framesPerSecond ?? 0,
      kbit_per_s: ((inbound.bytesReceived - last.bytesReceived) * 8) / 1000 / seconds,
      buffer_ms: emitted > 0 ? (buffered / emitted) * 1000 : null,
      decode_ms: decoded > 0 ? (decoding / decoded) * 1000 : null,
      frames_dropped: inbound.framesDropped ?? 0,
      codec: report.get(inbound.codecId)?.mimeType ?? "",
    };
  }

  #delete() {
    if (!this.location) return;
    fetch(this.location, {
      method: "DELETE",
      credentials: "same-origin",
      headers: { "X-CSRFToken": csrfToken() },
      keepalive: true, // outlives the page when it is closed
    }).catch(() => {});
    this.location = null;
  }

  stop() {
    this.stopped = true;
    clearTimeout(this.firstFrame);
    this.#delete();
    this.peer?.close();
    this.video.srcObject = null;
  }
}

/** Resolves when `peer` has gathered its candidates, or after GATHER_MS. */
function gathered(peer) {
  if (peer.iceGatheringState === "complete") return Promise.resolve();
  return new Promise((resolve) => {
    const done = () => {
      if (peer.iceGatheringState !== "complete") return;
      peer.removeEventListener("icegatheringstatechange", done);
      resolve();
    };
    peer.addEventListener("icegatheringstatechange", done);
    setTimeout(resolve, GATHER_MS);
  });
}
