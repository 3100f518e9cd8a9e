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
