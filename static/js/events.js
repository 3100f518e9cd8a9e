// The dashboard's open alerts (acknowledged by operators and admins) and recent events,
// from /api/events/.

import { api } from "./api.js";
import { ago, badge, el } from "./page.js";

const SEVERITY = { info: "info", warning: "warn", error: "danger" };

export class EventsPanel {
  constructor({ alerts, alertsEmpty, alertsOpen, events, eventsEmpty, mayAcknowledge }) {
    Object.assign(this, { alerts, alertsEmpty, alertsOpen, events, eventsEmpty, mayAcknowledge });
  }

  async refresh() {
    try {
      const [open, recent] = await Promise.all([api.get("/api/events/?alerts=open&limit=50"), api.get("/api/events/?limit=15")]);
      this.#render(open, recent);
    } catch {
      this.alertsOpen.textContent = "?";
    }
  }

  #render(open, recent) {
    this.alertsOpen.textContent = String(open.length);
    this.alertsOpen.className = `badge ${open.length ? "danger" : "plain"}`;
    this.alerts.replaceChildren(...open.map((event) => this.#alertRow(event)));
    this.alertsEmpty.hidden = open.length > 0;
    this.events.replaceChildren(...recent.map((event) => eventRow(event)));
    this.eventsEmpty.hidden = recent.length > 0;
  }

  #alertRow(event) {
    const acknowledge = this.mayAcknowledge
      ? el("button", { class: "btn small", type: "button", onclick: () => this.#acknowledge(event.id) }, "Acknowledge")
      : null;
    return el("tr", { dataset: { event: event.id, kind: event.kind } },
      el("td", {}, badge(event.kind.replaceAll("_", " "), SEVERITY[event.severity] || "")),
      el("td", { class: "wrap" }, event.message, el("div", { class: "muted small" }, `${ago(event.time)} · ${event.building || ""}`)),
      el("td", {}, acknowledge));
  }

  async #acknowledge(id) {
    await api.post(`/api/events/${id}/acknowledge`).catch(() => null);
    window.dispatchEvent(new Event("cloudnav:alerts"));
    await this.refresh();
  }
}

function eventRow(event) {
  return el("tr", { dataset: { event: event.id, kind: event.kind } },
    el("td", { class: "muted" }, ago(event.time)),
    el("td", {}, badge(event.kind.replaceAll("_", " "), SEVERITY[event.severity] || "")),
    el("td", { class: "wrap" }, event.message));
}
