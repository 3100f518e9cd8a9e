// A rolling time plot drawn by uPlot: the last `windowSeconds` of a few series, drawn
// again at most a few times a second, with a symmetric y axis that grows to fit.

import uPlot from "../vendor/uplot.js";

const GRID = "#e1e5ee";
const AXIS_TEXT = "#66708a";
const REDRAW_MS = 100;
const DEFAULT_HEIGHT = 140;
const TICK_S = 15;

export class TimePlot {
  /** `element`: the box the plot fills; `series`: [{label, color}]. */
  constructor(element, series, { windowSeconds = 60, minRange = 0.2 } = {}) {
    this.element = element;
    this.windowSeconds = windowSeconds;
    this.minRange = minRange;
    this.times = [];
    this.values = series.map(() => []);
    this.lastDraw = 0;
    this.timer = null;
    this.chart = new uPlot(this.#options(series), this.#data(), element);
    new ResizeObserver(() => this.#resize()).observe(element);
  }

  /** Add one sample of every series at `time` (seconds). */
  push(time, values) {
    this.times.push(time);
    values.forEach((value, index) => this.values[index].push(value));
    const cutoff = time - this.windowSeconds;
    let old = 0;
    while (old < this.times.length && this.times[old] < cutoff) old += 1;
    if (old) {
      this.times.splice(0, old);
      for (const list of this.values) list.splice(0, old);
    }
    this.#schedule();
  }

  /** Forget every sample (a replay seeking, or going back to live). */
  clear() {
    this.times = [];
    this.values = this.values.map(() => []);
    this.#schedule();
  }

  /** The time of the newest sample, or null. */
  newest() {
    return this.times.length ? this.times[this.times.length - 1] : null;
  }

  latest(index) {
    const list = this.values[index];
    return list.length ? list[list.length - 1] : null;
  }

  #options(series) {
    const axis = { stroke: AXIS_TEXT, grid: { stroke: GRID, width: 1 }, ticks: { show: false }, font: "11px system-ui, sans-serif" };
    return {
      width: this.element.clientWidth || 300,
      height: this.element.clientHeight || DEFAULT_HEIGHT,
      legend: { show: false },
      cursor: { show: false },
      series: [{}, ...series.map((s) => ({ label: s.label, stroke: s.color, width: 2, points: { show: false } }))],
      scales: {
        // x is seconds before the newest sample: the plot ends at "now".
        x: { time: false, range: () => [-this.windowSeconds, 0] },
        y: { range: () => { const r = this.#range(); return [-r, r]; } },
      },
      axes: [
        { ...axis, splits: () => this.#secondTicks(), values: (_, ticks) => ticks.map((t) => (t ? `${t}s` : "now")) },
        { ...axis, size: 44, splits: () => this.#valueTicks(), values: (_, ticks) => ticks.map(formatTick) },
      ],
    };
  }

  #data() {
    const now = this.newest() ?? 0;
    return [this.times.map((time) => time - now), ...this.values];
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
    this.chart.setData(this.#data());
  }

  #resize() {
    const width = this.element.clientWidth;
    if (width) this.chart.setSize({ width, height: this.element.clientHeight || DEFAULT_HEIGHT });
  }

  #valueTicks() {
    const range = this.#range();
    return [-range, -range / 2, 0, range / 2, range];
  }

  #secondTicks() {
    const ticks = [];
    for (let seconds = this.windowSeconds - TICK_S; seconds >= 0; seconds -= TICK_S) ticks.push(-seconds);
    return ticks;
  }

  #range() {
    const values = this.values.flat().map(Math.abs).filter(Number.isFinite);
    return niceCeiling(Math.max(this.minRange, ...values) * 1.1);
  }
}

function formatTick(value) {
  return Math.abs(value) < 1e-9 ? "0" : Number(value.toPrecision(2)).toString();
}

function niceCeiling(value) {
  const power = 10 ** Math.floor(Math.log10(value));
  return [1, 2, 4, 10].map((step) => step * power).find((limit) => limit >= value);
}
