// Topic rates and bandwidth (like `rostopic hz` and `bw`) of what this page receives, and
// the round trip of a `rosapi/get_time` call as the connection's latency.

import { el, fixed, formatBytes } from "./page.js";

const REFRESH_MS = 1000;
const PING_MS = 2000;
const PINGS_KEPT = 30;

export class RatesPanel {
  constructor(connection, prefix, elements) {
    this.connection = connection;
    this.prefix = prefix;
    this.ui = elements;
    this.pings = [];
    setInterval(() => this.render(), REFRESH_MS);
    setInterval(() => this.ping(), PING_MS);
    connection.addEventListener("connected", () => this.ping());
  }

  async ping() {
    if (!this.connection.connected) return;
    const started = performance.now();
    try {
      await this.connection.call("rosapi/get_time", "rosapi/GetTime", {}, 3000);
      this.pings.push(performance.now() - started);
      if (this.pings.length > PINGS_KEPT) this.pings.shift();
    } catch {
      this.pings.push(Number.NaN);
    }
    this.#renderLatency();
  }

  render() {
    const rows = this.connection.meter
      .summary()
      .filter((row) => row.topic.startsWith(this.prefix));
    this.ui.table.replaceChildren(...rows.map((row) => el("tr", { dataset: { topic: row.topic } },
      el("td", { class: "mono" }, row.topic.slice(this.prefix.length) || row.topic),
      el("td", { class: "num hz" }, row.rate ? fixed(row.rate, 1) : "—"),
      el("td", { class: "num bw" }, `${formatBytes(row.bandwidth)}/s`),
      el("td", { class: "num" }, formatBytes(row.meanSize)),
      el("td", { class: "num" }, row.maxGap === null ? "—" : `${Math.round(row.maxGap)} ms`),
    )));
    this.ui.empty.hidden = rows.length > 0;
  }

  #renderLatency() {
    const good = this.pings.filter(Number.isFinite);
    const last = this.pings[this.pings.length - 1];
    const sorted = [...good].sort((a, b) => a - b);
    const mean = good.reduce((sum, value) => sum + value, 0) / (good.length || 1);
    const p95 = sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(sorted.length * 0.95))] : Number.NaN;
    this.ui.latency.textContent = Number.isFinite(last) ? `${last.toFixed(1)} ms` : "timeout";
    this.ui.latency.dataset.ms = Number.isFinite(last) ? last.toFixed(1) : "";
    this.ui.latencyDetail.textContent = good.length
      ? `mean ${mean.toFixed(1)} · min ${sorted[0].toFixed(1)} · p95 ${p95.toFixed(1)} ms (${good.length} calls)`
      : "";
  }
}
