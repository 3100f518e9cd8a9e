// Replay of a robot's recording on its page: a timeline with play, pause, speed and seek
// that feeds the page's own topic handlers (the same panels as live) from
// GET /api/robots/{name}/recording.json, fetched a window at a time ahead of the clock.
// The events the server derived for the robot (its /{robot}/events channel, as
// rosgraph_msgs/Log) are marks on the timeline, coloured by severity; a click seeks there.

import { api } from "./api.js";

const WINDOW_S = 60; // seconds of recording fetched at once
const AHEAD_S = 20; // fetch the next window when less than this is buffered
const BEFORE_S = 30; // on a seek, the seconds before the point replayed at once (trail, map)
const TICK_MS = 50;
const MAX_MARKS = 2000; // events drawn on the timeline at most
// rosgraph_msgs/Log levels as the events' severities
const SEVERITIES = { 2: "info", 4: "warning", 8: "error" };

// Dispatches `mode` when it starts or stops replaying (`active` says which).
export class Replay extends EventTarget {
  // robot: its name; handlers: Map of topic -> function(msg); reset(): clear the panels;
  // els: { toggle, bar, time, play, speed, clock, note, marks }
  constructor(robot, handlers, reset, els) {
    super();
    Object.assign(this, { robot, handlers, reset, els });
    this.active = false;
    this.playing = false;
    this.clock = 0;
    this.span = null;
    this.buffer = [];
    this.fetchedTo = 0;
    this.more = true;
    this.loading = null;
    this.timer = null;
    els.toggle.addEventListener("click", () => (this.active ? this.leave() : this.enter()));
    els.play.addEventListener("click", () => this.setPlaying(!this.playing));
    els.time.addEventListener("input", () => this.seek(Number(els.time.value)));
    els.speed.addEventListener("change", () => {});
  }

  url(start, end) {
    const topics = [...this.handlers.keys()].map((t) => t.split("/").slice(2).join("/")).join(",");
    return `/api/robots/${this.robot}/recording.json?start=${start}&end=${end}&topics=${topics}`;
  }

  async enter() {
    const now = Date.now() / 1000;
    const head = await api.get(`${this.url(now - 1, now)}&limit=1`);
    if (!head.span) {
      this.els.note.textContent = "Nothing recorded for this robot yet.";
      return;
    }
    this.active = true;
    this.span = head.span;
    const { time, bar, toggle } = this.els;
    time.min = String(head.span[0]);
    time.max = String(head.span[1]);
    time.step = "0.1";
    bar.hidden = false;
    toggle.textContent = "Back to live";
    toggle.classList.add("active");
    document.body.dataset.mode = "replay";
    this.dispatchEvent(new CustomEvent("mode"));
    this.els.note.textContent = "";
    await Promise.all([this.seek(head.span[0]), this.loadEvents()]);
  }

  // The robot's events over the whole recording, drawn as marks on the timeline.
  async loadEvents() {
    const { marks } = this.els;
    if (!marks) return;
    marks.replaceChildren();
    const [first, last] = this.span;
    const events = [];
    let start = first;
    while (events.length < MAX_MARKS) {
      const answer = await api.get(
        `/api/robots/${this.robot}/recording.json?start=${start}&end=${last + 1}&topics=events&limit=${MAX_MARKS}`,
      );
      events.push(...answer.messages);
      if (!answer.more) break;
      start = answer.next;
    }
    const width = Math.max(last - first, 1e-9);
    for (const { t, msg } of events.slice(0, MAX_MARKS)) {
      const mark = document.createElement("button");
      mark.type = "button";
      const severity = SEVERITIES[msg.level] || "info";
      mark.className = `replay-mark ${severity}`;
      mark.style.left = `${(Math.min(Math.max(t - first, 0), width) / width) * 100}%`;
      mark.dataset.t = String(t);
      mark.dataset.kind = msg.name;
      const when = new Date(t * 1000).toISOString().replace("T", " ").slice(0, 19);
      mark.title = `${when} ${msg.name}: ${msg.msg}`;
      mark.setAttribute("aria-label", mark.title);
      mark.addEventListener("click", () => this.seek(t));
      marks.append(mark);
    }
    marks.dataset.count = String(marks.childElementCount);
  }

  leave() {
    this.setPlaying(false);
    this.active = false;
    this.els.bar.hidden = true;
    this.els.toggle.textContent = "Recording";
    this.els.toggle.classList.remove("active");
    document.body.dataset.mode = "live";
    this.dispatchEvent(new CustomEvent("mode"));
    this.reset();
  }

  async seek(t) {
    this.clock = t;
    this.reset();
    this.buffer = [];
    this.more = true;
    this.fetchedTo = t - BEFORE_S;
    const generation = (this.generation = (this.generation || 0) + 1);
    await this.fetchAhead();
    if (generation !== this.generation) return;
    this.dispatchUntil(t);
    this.render();
  }

  async fetchAhead() {
    if (this.loading || !this.more) return this.loading;
    const start = this.fetchedTo;
    const end = Math.min(start + WINDOW_S, this.span[1] + 1);
    this.loading = api.get(this.url(start, end)).then((answer) => {
      this.buffer.push(...answer.messages);
      // a window cut short continues just after its last message; a whole one at its end
      this.fetchedTo = answer.more ? answer.next : end;
      this.more = answer.more || end < this.span[1];
    }).finally(() => { this.loading = null; });
    return this.loading;
  }

  dispatchUntil(t) {
    let i = 0;
    while (i < this.buffer.length && this.buffer[i].t <= t) {
      const { topic, msg } = this.buffer[i];
      const handle = this.handlers.get(topic);
      if (handle) handle(msg);
      i += 1;
    }
    this.buffer.splice(0, i);
  }

  setPlaying(playing) {
    this.playing = playing;
    this.els.play.textContent = playing ? "Pause" : "Play";
    clearInterval(this.timer);
    if (!playing) return;
    let last = performance.now();
    this.timer = setInterval(() => {
      const now = performance.now();
      this.clock = Math.min(this.clock + ((now - last) / 1000) * Number(this.els.speed.value), this.span[1]);
      last = now;
      this.dispatchUntil(this.clock);
      this.render();
      const buffered = this.fetchedTo - this.clock;
      if (buffered < AHEAD_S * Number(this.els.speed.value)) this.fetchAhead();
      if (this.clock >= this.span[1]) this.setPlaying(false);
    }, TICK_MS);
  }

  render() {
    this.els.time.value = String(this.clock);
    this.els.clock.textContent = new Date(this.clock * 1000).toISOString().replace("T", " ").slice(0, 21);
    this.els.bar.dataset.clock = this.clock.toFixed(1);
  }
}
