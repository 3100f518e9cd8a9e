// Missions on the building's live map: every active mission of the building (any operator
// sees them, and they outlive the page), with pause, resume, skip and cancel; operators
// plan one for the selected robot by pressing waypoints on the plan.

import { ApiError, api } from "./api.js";
import { badge, el } from "./page.js";

const POLL_MS = 2000;
const STATE_KIND = { running: "info", paused: "warn", done: "ok", cancelled: "idle" };
const $ = (id) => document.getElementById(id);

export class MissionsPanel {
  constructor({ building, plan, connection, mayDrive, hint }) {
    Object.assign(this, { building, plan, connection, mayDrive, hint });
    this.missions = [];
    this.draft = null; // {robot, points: [{map, x, y, yaw}]}
  }

  start() {
    if (this.mayDrive) this.#bindDraft();
    this.plan.addEventListener("select", () => this.#showWaypoints());
    this.refresh();
    setInterval(() => this.refresh(), POLL_MS);
  }

  async refresh() {
    try {
      this.missions = await api.get(`/api/missions/?building=${encodeURIComponent(this.building)}&active=1`);
    } catch {
      return;
    }
    $("mission-list").replaceChildren(...this.missions.map((m) => this.#row(m)));
    $("mission-empty").hidden = this.missions.length > 0;
    this.#showWaypoints();
  }

  #row(mission) {
    const progress = `waypoint ${mission.index + 1}/${mission.waypoints.length}${mission.mode === "patrol" ? ` · lap ${mission.laps + 1}` : ""}`;
    const button = (text, command) => el("button", { class: "btn small", type: "button", dataset: { command },
      onclick: (event) => { event.stopPropagation(); this.#command(mission, command); } }, text);
    const controls = this.mayDrive ? el("div", { class: "row" },
      mission.state === "paused" ? button("Resume", "resume") : button("Pause", "pause"),
      button("Skip", "skip"), button("Cancel", "cancel")) : null;
    return el("tr", { class: "clickable", dataset: { mission: mission.id, robot: mission.robot, state: mission.state },
      onclick: () => this.plan.select(mission.robot) },
    el("td", { class: "wrap" }, el("strong", {}, mission.robot), " ", mission.name ? el("span", { class: "muted" }, mission.name) : null,
      el("div", { class: "muted small progress" }, progress), mission.note ? el("div", { class: "muted small" }, mission.note) : null),
    el("td", {}, badge(mission.state, STATE_KIND[mission.state] || "")),
    el("td", {}, controls));
  }

  async #command(mission, command) {
    // Pausing or cancelling also stops the robot at once: it drops the goal it drives to.
    if (command === "pause" || command === "cancel") {
      this.connection.call(`/${mission.robot}/cancel_goal`, "std_srvs/Trigger", {}).catch(() => {});
    }
    await api.post(`/api/missions/${mission.id}/${command}`).catch((error) => this.hint(error.message));
    await this.refresh();
  }

  /** The selected robot's active mission on the plan, or the draft being planned. */
  #showWaypoints() {
    const points = this.draft ? this.draft.points
      : this.missions.find((m) => m.robot === this.plan.selected)?.waypoints || [];
    this.plan.waypoints = points.map(({ x, y, yaw }) => ({ x, y, yaw }));
    this.plan.changed();
  }

  // ------------------------------------------------------------ planning

  #bindDraft() {
    $("mission-plan").addEventListener("click", () => this.#beginDraft());
    $("mission-undo").addEventListener("click", () => {
      this.draft?.points.pop();
      this.#renderDraft();
    });
    $("mission-discard").addEventListener("click", () => this.#endDraft());
    $("mission-start").addEventListener("click", () => this.#startDraft());
    this.plan.addEventListener("pose", ({ detail }) => {
      if (detail.tool !== "waypoint" || !this.draft) return;
      if (!detail.map) {
        this.hint("That point is outside every sub-map: no waypoint added.");
      } else {
        this.draft.points.push({ map: detail.map, ...detail.pose });
        this.#renderDraft();
      }
      this.plan.setTool("waypoint"); // keep adding
    });
  }

  #beginDraft() {
    const robot = this.plan.selected;
    if (!robot) {
      this.hint("Click a robot on the plan (or in the list) first: the mission is for it.");
      return;
    }
    this.draft = { robot, points: [] };
    this.plan.setTool("waypoint");
    this.hint(`Press each waypoint of ${robot}'s mission on the plan; drag for its heading.`);
    this.#renderDraft();
  }

  #endDraft() {
    this.draft = null;
    this.plan.setTool(null);
    this.hint("");
    this.#renderDraft();
  }

  #renderDraft() {
    $("mission-draft").hidden = !this.draft;
    if (this.draft) {
      $("mission-draft-help").textContent = `Mission for ${this.draft.robot}: press on the plan for each waypoint, dragging towards its heading.`;
      $("mission-draft-points").replaceChildren(...this.draft.points.map((p) => el("li", {}, `${p.map} · ${p.x.toFixed(2)}, ${p.y.toFixed(2)}`)));
      $("mission-start").disabled = this.draft.points.length === 0;
    }
    $("mission-error").hidden = true;
    this.#showWaypoints();
  }

  async #startDraft() {
    const body = {
      building: this.building,
      robot: this.draft.robot,
      name: $("mission-name").value,
      mode: $("mission-mode").value,
      waypoints: this.draft.points,
    };
    try {
      await api.post("/api/missions/", body);
      this.#endDraft();
      await this.refresh();
    } catch (error) {
      $("mission-error").hidden = false;
      $("mission-error").textContent = error instanceof ApiError ? error.messages.join("; ") : error.message;
    }
  }
}
