// Glass-to-glass delay in the browser: the time code a camera stamps into its pictures
// (`telemetry/domain/timecode.py`: Unix milliseconds modulo 2^42 as 42 black or white
// cells across the top, under a row of alternating cells), read back from the picture
// as it is shown, by the same rule as the Python reader, and compared with this clock.
// A <video> is read when each frame is about to be shown (requestVideoFrameCallback,
// at its expected display time); an <img> (MJPEG) once per animation frame, which adds
// up to one display refresh (about 16 ms) to what it measures.

const BITS = 42;
const MODULO = 2 ** BITS;
const WINDOW_MS = 10_000; // delays of the pictures shown this long ago at most are kept
const KEEP = 1200; // and at most this many (120 frames/s)

/** A cell's width and height in pixels for a picture of this size (as the Python side). */
export function cellSize(width, height) {
  return [Math.floor(width / BITS), Math.max(8, Math.floor(height / 48))];
}

/** The milliseconds stamped in `image` (an ImageData of at least the code's two rows of a
 * picture `width` wide and `height` high), or null when it carries no time code. */
export function readTimecode(image, width, height) {
  const [cw, ch] = cellSize(width, height);
  if (cw < 1) return null;
  let value = 0;
  for (let i = 0; i < BITS; i += 1) {
    // The middle of each cell only: codecs smear the edges.
    const x0 = i * cw + Math.floor(cw / 4);
    const x1 = (i + 1) * cw - Math.floor(cw / 4);
    const check = meanGrey(image, x0, x1, Math.floor(ch / 4), ch - Math.floor(ch / 4)) > 128;
    if (check !== (i % 2 === 0)) return null;
    const bit = meanGrey(image, x0, x1, ch + Math.floor(ch / 4), 2 * ch - Math.floor(ch / 4)) > 128;
    value = value * 2 + (bit ? 1 : 0);
  }
  return value;
}

function meanGrey(image, x0, x1, y0, y1) {
  const { data, width } = image;
  let sum = 0;
  let count = 0;
  for (let y = y0; y < y1; y += 1) {
    for (let x = x0; x < x1; x += 1) {
      const at = (y * width + x) * 4;
      sum += data[at] + data[at + 1] + data[at + 2];
      count += 3;
    }
  }
  return count ? sum / count : 0;
}

/** Milliseconds between a picture `stamped` and `nowMillis` (both Unix ms). */
export function delayMs(stamped, nowMillis) {
  return (((nowMillis - stamped) % MODULO) + MODULO) % MODULO;
}

/** The `p`th percentile (0..100) of `values`, nearest rank; null when there are none. */
export function percentile(values, p) {
  if (!values.length) return null;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.min(sorted.length - 1, Math.max(0, Math.ceil((p / 100) * sorted.length) - 1))];
}

/** Reads the time code of every new picture a <video> or <img> shows and keeps the delays. */
export class DelayMeter {
  constructor(element) {
    this.element = element;
    this.delays = [];
    this.shownAt = []; // when each kept picture was shown (Unix ms)
    this.count = 0; // pictures read, all time
    this.recording = null;
    this.last = null;
    this.canvas = document.createElement("canvas");
    this.ctx = this.canvas.getContext("2d", { willReadFrequently: true });
    this.stopped = false;
    if (element instanceof HTMLVideoElement && "requestVideoFrameCallback" in element) this.#onVideoFrame();
    else this.#onAnimationFrame();
  }

  #onVideoFrame() {
    const video = this.element;
    video.requestVideoFrameCallback((now, metadata) => {
      if (this.stopped) return;
      // When the frame is expected on the screen, on the Unix clock.
      const shownAt = Date.now() + (metadata.expectedDisplayTime - performance.now());
      this.#read(video, metadata.width, metadata.height, shownAt);
      this.#onVideoFrame();
    });
  }

  #onAnimationFrame() {
    requestAnimationFrame(() => {
      if (this.stopped) return;
      const img = this.element;
      if (img.complete && img.naturalWidth) this.#read(img, img.naturalWidth, img.naturalHeight, Date.now());
      this.#onAnimationFrame();
    });
  }

  #read(source, width, height, shownAt) {
    const rows = 2 * cellSize(width, height)[1];
    if (this.canvas.width !== width || this.canvas.height !== rows) {
      this.canvas.width = width;
      this.canvas.height = rows;
    }
    this.ctx.drawImage(source, 0, 0, width, rows, 0, 0, width, rows);
    const stamped = readTimecode(this.ctx.getImageData(0, 0, width, rows), width, height);
    if (stamped === null || stamped === this.last) return;
    this.last = stamped;
    this.count += 1;
    this.delays.push(delayMs(stamped, shownAt));
    this.shownAt.push(shownAt);
    this.recording?.push(this.delays.at(-1));
    let old = 0;
    while (old < this.shownAt.length && (this.shownAt[old] < shownAt - WINDOW_MS || this.shownAt.length - old > KEEP)) old += 1;
    this.delays.splice(0, old);
    this.shownAt.splice(0, old);
  }

  /** Delay p50 and p95 (ms) of the pictures of the last 10 s, and how many were read in all. */
  summary() {
    return { p50: percentile(this.delays, 50), p95: percentile(this.delays, 95), count: this.count };
  }

  /** From now on keep every delay in `recording` as well (a benchmark, after its warm-up). */
  record() {
    this.recording = [];
  }

  stop() {
    this.stopped = true;
  }
}
