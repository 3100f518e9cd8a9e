// The camera panel: the robot's camera through the video relays, MJPEG as an <img> or VP8
// as a live WebM stream played through Media Source Extensions fed by fetch (a plain
// <video src> on an endless WebM stalls in Chromium), or straight from the rosbridge topic
// when the relays are not available. Counts the frames it shows.

const LIVE_EDGE_S = 0.3;
const MAX_LAG_S = 1.0;
const KEEP_S = 10;
const STATS_MS = 2000;

export function streamUrl(topic, type) {
  return `/stream?topic=${encodeURIComponent(topic)}&type=${type}`;
}

export class CameraPanel {
  constructor(connection, topic, elements) {
    this.connection = connection;
    this.topic = topic;
    this.ui = elements;
    this.mode = null;
    this.frames = 0;
    this.stopCurrent = () => {};
    for (const button of elements.modes.querySelectorAll("button[data-mode]")) {
      button.addEventListener("click", () => this.show(button.dataset.mode));
    }
    setInterval(() => this.#renderRate(), 1000);
    this.lastCount = { at: performance.now(), frames: 0 };
  }

  show(mode) {
    this.stopCurrent();
    this.mode = mode;
    this.frames = 0;
    this.#message("Waiting for frames…");
    for (const button of this.ui.modes.querySelectorAll("button[data-mode]")) {
      button.classList.toggle("active", button.dataset.mode === mode);
    }
    this.ui.frame.dataset.mode = mode;
    const start = { mjpeg: () => this.#mjpeg(), vp8: () => this.#vp8(), topic: () => this.#viaTopic() };
    this.stopCurrent = start[mode]();
  }

  #frame() {
    this.frames += 1;
    this.ui.frame.dataset.frames = String(this.frames);
    if (this.frames === 1) this.#message("");
  }

  #message(text) {
    this.ui.note.textContent = text;
    this.ui.note.hidden = !text;
  }

  #mjpeg() {
    const img = this.#mount("img", { alt: "", title: "camera (MJPEG)" });
    img.addEventListener("load", () => this.#frame());
    img.addEventListener("error", () => {
      // Without the relay, the rosbridge topic still carries the same JPEG frames.
      this.show("topic");
      this.#message("The MJPEG relay is not available: showing the rosbridge topic.");
    });
    img.src = streamUrl(this.topic, "mjpeg");
    // An MJPEG <img> fires `load` once; count the later frames by sampling its pixels.
    const watcher = new FrameWatcher(img, () => this.#frame());
    return () => {
      watcher.stop();
      img.removeAttribute("src");
      img.remove();
    };
  }

  #vp8() {
    const video = this.#mount("video", { muted: true, autoplay: true, playsinline: true });
    const player = new LiveWebm(video, streamUrl(this.topic, "vp8"), (error) => this.#message(error));
    if ("requestVideoFrameCallback" in video) {
      const count = () => {
        this.#frame();
        if (video.isConnected) video.requestVideoFrameCallback(count);
      };
      video.requestVideoFrameCallback(count);
    }
    return () => {
      player.stop();
      video.remove();
    };
  }

  #viaTopic() {
    const img = this.#mount("img", { alt: "", title: "camera (rosbridge topic)" });
    const unsubscribe = this.connection.subscribe(this.topic, "sensor_msgs/CompressedImage", (msg) => {
      img.src = `data:image/${msg.format?.includes("png") ? "png" : "jpeg"};base64,${msg.data}`;
      this.#frame();
    }, { queue_length: 1 });
    return () => {
      unsubscribe();
      img.remove();
    };
  }

  #mount(tag, attributes) {
    const node = document.createElement(tag);
    for (const [key, value] of Object.entries(attributes)) {
      node[key] = value;
      if (value === true) node.setAttribute(key, "");
    }
    this.ui.frame.prepend(node);
    return node;
  }

  #renderRate() {
    const now = performance.now();
    const fps = ((this.frames - this.lastCount.frames) * 1000) / (now - this.lastCount.at);
    this.lastCount = { at: now, frames: this.frames };
    this.ui.fps.textContent = `${Math.max(0, fps).toFixed(1)} fps shown · ${this.frames} frames`;
  }

  /** Poll the relays' statistics, if the server has them, and show this topic's. */
  watchStats(url) {
    const poll = async () => {
      const response = await fetch(url, { credentials: "same-origin" }).catch(() => null);
      if (!response?.ok) {
        this.ui.stats.hidden = true;
        return;
      }
      const entries = statsFor(await response.json(), this.topic);
      this.ui.stats.hidden = entries.length === 0;
      this.ui.stats.textContent = entries.map(([key, value]) => `${key}: ${value}`).join(" · ");
      setTimeout(poll, STATS_MS);
    };
    poll();
  }
}

/** The scalar fields of the statistics about `topic` in whatever shape the relay serves. */
export function statsFor(data, topic) {
  const entries = Array.isArray(data) ? data : Object.values(data?.streams || data || {});
  const matching = entries.find((entry) => JSON.stringify(entry).includes(topic)) ?? (data?.[topic] || null);
  if (!matching || typeof matching !== "object") return [];
  return Object.entries(matching)
    .filter(([, value]) => ["number", "string"].includes(typeof value) && value !== topic)
    .slice(0, 8)
    .map(([key, value]) => [key, typeof value === "number" ? Number(value.toFixed(2)) : value]);
}

/** Notices new MJPEG frames by comparing a tiny sample of the picture a few times a second. */
class FrameWatcher {
  constructor(img, onFrame) {
    const canvas = document.createElement("canvas");
    canvas.width = 16;
    canvas.height = 12;
    const ctx = canvas.getContext("2d", { willReadFrequently: true });
    let last = "";
    this.timer = setInterval(() => {
      if (!img.naturalWidth) return;
      ctx.drawImage(img, 0, 0, canvas.width, canvas.height);
      const sample = ctx.getImageData(0, 0, canvas.width, canvas.height).data.join(",");
      if (sample !== last && last) onFrame();
      last = sample;
    }, 100);
  }

  stop() {
    clearInterval(this.timer);
  }
}

/** A live `video/webm` stream fed to a <video> through Media Source Extensions. */
class LiveWebm {
  constructor(video, url, onError) {
    this.video = video;
    this.abort = new AbortController();
    this.onError = onError;
    const type = 'video/webm; codecs="vp8"';
    if (!window.MediaSource || !MediaSource.isTypeSupported(type)) {
      onError("This browser cannot play VP8 through Media Source Extensions.");
      return;
    }
    this.source = new MediaSource();
    video.src = URL.createObjectURL(this.source);
    this.source.addEventListener("sourceopen", () => this.#feed(url, type), { once: true });
  }

  async #feed(url, type) {
    const buffer = this.source.addSourceBuffer(type);
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
    if (!buffer.buffered.length) return;
    const end = buffer.buffered.end(buffer.buffered.length - 1);
    if (end - video.currentTime > MAX_LAG_S) video.currentTime = end - LIVE_EDGE_S;
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
