// The camera panel: the robot's camera through the video relays, WebRTC by WHEP (the
// default), MJPEG as an <img> or VP8 as a live WebM stream played through Media Source
// Extensions (`liveplayer.js`), or straight from the rosbridge topic when the relays are
// not available. WebRTC that fails falls back to MJPEG by itself. Counts the frames it
// shows, and shows the relay's figures of the very stream it plays (and, for WebRTC, the
// browser's own: frame rate, bitrate, delay in its jitter buffer and decoder). When the
// camera stamps a time code into its pictures, it shows the glass-to-glass delay it reads
// back from the pictures it shows (`timecode.js`). When the pictures stop coming it says
// the camera is stalled, and clears that when they come again.

import { LiveRtcPlayer, LiveWebmPlayer } from "./liveplayer.js";
import { el, fixed } from "./page.js";
import { DelayMeter } from "./timecode.js";

const STATS_MS = 2000;
// No new picture for this long (or four of the camera's recent intervals, if longer):
// stalled. The simulated camera sends 5 pictures/s, a real one 10 to 30.
const STALL_MS = 2000;
// What the relay's statistics call each mode's stream (`topic`: the camera as published).
const STATS_TYPE = { webrtc: "webrtc/vp8", mjpeg: "mjpeg", vp8: "vp8", topic: "source" };

export function streamUrl(topic, type) {
  return `/stream?topic=${encodeURIComponent(topic)}&type=${type}`;
}

export function whepUrl(topic, type = "vp8") {
  return `/whep?topic=${encodeURIComponent(topic)}&type=${type}`;
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
    this.lastFrameAt = 0;
    this.interval = 0; // ms between pictures, smoothed
    this.meter = null;
  }

  show(mode) {
    this.stopCurrent();
    this.meter?.stop();
    this.meter = null;
    this.mode = mode;
    this.frames = 0;
    this.interval = 0;
    this.#stalled(false);
    this.#message("Waiting for frames…");
    for (const button of this.ui.modes.querySelectorAll("button[data-mode]")) {
      button.classList.toggle("active", button.dataset.mode === mode);
    }
    this.ui.frame.dataset.mode = mode;
    this.ui.stats.hidden = true; // until the figures of this mode's stream arrive
    this.ui.rtc.hidden = true;
    delete this.ui.frame.dataset.fallback;
    delete this.ui.frame.dataset.fallbackReason;
    for (const key of ["delayP50", "delayP95", "delayCount"]) delete this.ui.frame.dataset[key];
    const start = {
      webrtc: () => this.#webrtc(),
      mjpeg: () => this.#mjpeg(),
      vp8: () => this.#vp8(),
      topic: () => this.#viaTopic(),
    };
    this.stopCurrent = start[mode]();
  }

  #frame() {
    const now = performance.now();
    if (this.frames > 0) this.interval = this.interval ? 0.9 * this.interval + 0.1 * (now - this.lastFrameAt) : now - this.lastFrameAt;
    this.lastFrameAt = now;
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

  #webrtc() {
    const video = this.#mount("video", { muted: true, autoplay: true, playsinline: true });
    const player = new LiveRtcPlayer(video, whepUrl(this.topic), (error) => {
      this.show("mjpeg");
      this.ui.frame.dataset.fallback = "mjpeg";
      this.ui.frame.dataset.fallbackReason = error;
      this.#message(`${error}: showing MJPEG.`);
    });
    this.rtc = player;
    this.#countFrames(video);
    const timer = setInterval(() => this.#renderRtc(player), 1000);
    return () => {
      clearInterval(timer);
      player.stop();
      this.rtc = null;
      video.remove();
    };
  }

  async #renderRtc(player) {
    const stats = await player.stats();
    if (!stats || this.rtc !== player) return;
    this.ui.frame.dataset.rtcFps = stats.fps.toFixed(1);
    this.ui.frame.dataset.rtcKbits = stats.kbit_per_s.toFixed(0);
    this.ui.rtc.hidden = false;
    this.ui.rtc.replaceChildren(
      ...figures([
        ["WebRTC received", `${fixed(stats.fps, 1)} fps · ${fixed(stats.kbit_per_s, 0)} kbit/s · ${stats.codec}`],
        ["Delay in the browser", `jitter buffer ${ms(stats.buffer_ms)} · decode ${ms(stats.decode_ms)}`],
        ["Frames dropped here", String(stats.frames_dropped)],
      ]),
    );
  }

  #countFrames(video) {
    if (!("requestVideoFrameCallback" in video)) return;
    const count = () => {
      this.#frame();
      if (video.isConnected) video.requestVideoFrameCallback(count);
    };
    video.requestVideoFrameCallback(count);
  }

  #vp8() {
    const video = this.#mount("video", { muted: true, autoplay: true, playsinline: true });
    const player = new LiveWebmPlayer(video, streamUrl(this.topic, "vp8"), (error) => this.#message(error));
    this.player = player;
    this.#countFrames(video);
    return () => {
      player.stop();
      this.player = null;
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
    this.meter = new DelayMeter(node);
    return node;
  }

  #stalled(stalled, seconds = 0) {
    const badge = this.ui.stalled;
    if (stalled) this.ui.frame.dataset.stalled = "true";
    else delete this.ui.frame.dataset.stalled;
    if (!badge) return;
    badge.hidden = !stalled;
    badge.textContent = stalled ? `Stalled: no new picture for ${seconds.toFixed(0)} s` : "";
  }

  #renderRate() {
    const now = performance.now();
    const fps = ((this.frames - this.lastCount.frames) * 1000) / (now - this.lastCount.at);
    this.lastCount = { at: now, frames: this.frames };
    this.ui.fps.dataset.fps = Math.max(0, fps).toFixed(1);
    const shown = [["Shown here", `${Math.max(0, fps).toFixed(1)} fps · ${this.frames} frames`]];
    const delay = this.meter?.summary();
    if (delay?.p50 !== null && delay?.p50 !== undefined) {
      shown.push(["Glass to glass", `p50 ${Math.round(delay.p50)} ms · p95 ${Math.round(delay.p95)} ms`]);
      Object.assign(this.ui.frame.dataset, { delayP50: delay.p50, delayP95: delay.p95, delayCount: delay.count });
    }
    this.ui.fps.replaceChildren(...figures(shown));
    const quiet = now - this.lastFrameAt;
    this.#stalled(this.frames > 0 && quiet > Math.max(STALL_MS, 4 * this.interval), quiet / 1000);
  }

  /** Poll the relay's statistics of the stream this panel plays, and show them. */
  watchStats(url) {
    const poll = async () => {
      const query = new URLSearchParams({ topic: this.topic, type: STATS_TYPE[this.mode] || "" });
      const response = await fetch(`${url}?${query}`, { credentials: "same-origin" }).catch(() => null);
      if (response?.ok) this.#renderStats((await response.json()).streams[0], STATS_TYPE[this.mode]);
      else this.ui.stats.hidden = true;
      setTimeout(poll, STATS_MS);
    };
    poll();
  }

  #renderStats(stream, type) {
    this.ui.stats.hidden = !stream;
    if (!stream) return;
    this.ui.stats.dataset.type = type;
    this.ui.stats.replaceChildren(...figures(streamFigures(stream, type)));
  }
}

/** A delay in milliseconds as a person reads it; "—" when there is none. */
const ms = (value) => (value === null || value === undefined ? "—" : `${Math.round(value)} ms`);

/** The relay's stamp-to-sent delays of `stream` in words; when the camera stamps by a
 * clock far off the server's, that offset is said instead (it is no delay). */
export function stampDelay(stream) {
  const offset = stream.clock_offset_ms;
  if (offset !== null && offset !== undefined) {
    const way = offset > 0 ? "behind" : "ahead of";
    return `— (the camera's clock is ${Math.round(Math.abs(offset) / 1000)} s ${way} the server's)`;
  }
  return `p50 ${ms(stream.delay_p50_ms)} · p99 ${ms(stream.delay_p99_ms)}`;
}

/** The relay's figures of one stream as [label, value] pairs a person reads. */
export function streamFigures(stream, type) {
  const rate = `${fixed(stream.fps, 1)} fps · ${fixed(stream.kB_per_s, 1)} kB/s`;
  if (type === "source") {
    return [
      ["Camera publishes", rate],
      ["Delay to the server", stampDelay(stream)],
    ];
  }
  return [
    ["Server sends", rate],
    ["Stream", stream.params],
    ["Delay, stamp to sent", stampDelay(stream)],
    ["Encoder", `${fixed(stream.encoder_cpu * 100, 1)} % of a core`],
    ["Viewers", String(stream.viewers)],
    ["Frames skipped", String(stream.frames_skipped)],
  ];
}

/** <dt>/<dd> pairs of a `<dl class="kv">`. */
function figures(pairs) {
  return pairs.flatMap(([label, value]) => [el("dt", {}, label), el("dd", {}, value)]);
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
