// A rolling time plot on a canvas: the last `windowSeconds` of a few series, drawn at most
// a few times a second, with a symmetric y axis that grows to fit.

const GRID = "#e1e5ee";
const AXIS_TEXT = "#66708a";
const REDRAW_MS = 100;

export class TimePlot {
  /** `series`: [{label, color, unit}]. */
  constructor(canvas, series, { windowSeconds = 60, minRange = 0.2 } = {}) {
    this.canvas = canvas;
    this.series = series.map((s) => ({ ...s, points: [] }));
    this.windowSeconds = windowSeconds;
    this.minRange = minRange;
    this.lastDraw = 0;
    this.timer = null;
    new ResizeObserver(() => this.draw()).observe(canvas);
  }

  /** Add one sample of every series at `time` (seconds). */
  push(time, values) {
    this.series.forEach((series, index) => {
      series.points.push([time, values[index]]);
      const cutoff = time - this.windowSeconds;
      while (series.points.length && series.points[0][0] < cutoff) series.points.shift();
    });
    this.#schedule();
  }

  /** Forget every sample (a replay seeking, or going back to live). */
  clear() {
    for (const series of this.series) series.points = [];
    this.#schedule();
  }

  /** The time of the newest sample, or null. */
  newest() {
    const times = this.series.flatMap((s) => (s.points.length ? [s.points[s.points.length - 1][0]] : []));
    return times.length ? Math.max(...times) : null;
  }

  latest(index) {
    const points = this.series[index].points;
    return points.length ? points[points.length - 1][1] : null;
  }

  #schedule() {
    if (this.timer) return;
    const wait = Math.max(0, REDRAW_MS - (performance.now() - this.lastDraw));
    this.timer = setTimeout(() => {
      this.timer = null;
      this.draw();
    }, wait);
  }

  draw() {
    this.lastDraw = performance.now();
    const { ctx, width, height } = this.#surface();
    const box = { left: 44, right: width - 8, top: 8, bottom: height - 20 };
    const now = this.#now();
    const range = this.#range();
    const toX = (t) => box.left + ((t - (now - this.windowSeconds)) / this.windowSeconds) * (box.right - box.left);
    const toY = (v) => box.top + ((range - v) / (2 * range)) * (box.bottom - box.top);
    drawAxes(ctx, box, range, toY, this.windowSeconds);
    for (const series of this.series) drawSeries(ctx, series, toX, toY);
  }

  #surface() {
    const ratio = window.devicePixelRatio || 1;
    const width = this.canvas.clientWidth || 300;
    const height = this.canvas.clientHeight || 140;
    this.canvas.width = Math.round(width * ratio);
    this.canvas.height = Math.round(height * ratio);
    const ctx = this.canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.clearRect(0, 0, width, height);
    return { ctx, width, height };
  }

  #now() {
    return this.newest() ?? 0;
  }

  #range() {
    const values = this.series.flatMap((s) => s.points.map(([, v]) => Math.abs(v)));
    const peak = Math.max(this.minRange, ...values.filter(Number.isFinite));
    return niceCeiling(peak * 1.1);
  }
}

function drawAxes(ctx, box, range, toY, windowSeconds) {
  ctx.font = "11px system-ui, sans-serif";
  ctx.fillStyle = AXIS_TEXT;
  ctx.strokeStyle = GRID;
  ctx.lineWidth = 1;
  ctx.textAlign = "right";
  for (const value of [-range, -range / 2, 0, range / 2, range]) {
    const y = Math.round(toY(value)) + 0.5;
    ctx.beginPath();
    ctx.moveTo(box.left, y);
    ctx.lineTo(box.right, y);
    ctx.stroke();
    ctx.fillText(formatTick(value), box.left - 6, y + 4);
  }
  ctx.textAlign = "center";
  for (let seconds = 0; seconds < windowSeconds; seconds += 15) {
    const x = box.left + (1 - seconds / windowSeconds) * (box.right - box.left);
    ctx.fillText(seconds ? `-${seconds}s` : "now", Math.min(x, box.right - 12), box.bottom + 15);
  }
}

function drawSeries(ctx, series, toX, toY) {
  if (series.points.length < 2) return;
  ctx.strokeStyle = series.color;
  ctx.lineWidth = 2;
  ctx.lineJoin = "round";
  ctx.beginPath();
  series.points.forEach(([t, v], index) => {
    if (index === 0) ctx.moveTo(toX(t), toY(v));
    else ctx.lineTo(toX(t), toY(v));
  });
  ctx.stroke();
}

function formatTick(value) {
  return Math.abs(value) < 1e-9 ? "0" : Number(value.toPrecision(2)).toString();
}

function niceCeiling(value) {
  const power = 10 ** Math.floor(Math.log10(value));
  return [1, 2, 4, 10].map((step) => step * power).find((limit) => limit >= value);
}
