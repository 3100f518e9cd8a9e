// The fleet dashboard: every visible robot from /api/fleet/, kept live over rosbridge
// (pose for the sub-map, odometry for the speed, nav_status for navigation, localisation
// for whether it knows where it is).

import { api, splitMapId, urls } from "./api.js";
import { EventsPanel } from "./events.js";
import { heardRecently } from "./liveness.js";
import { ago, badge, connectFleet, el, fixed, navigationState, pageConfig, whereabouts } from "./page.js";

const POLL_MS = 3000;
// How a lost robot is got out, said to whoever reads the dashboard.
const WAY_OUT = ["operator", "admin"].includes(pageConfig().role)
  ? "Open it to set its initial pose, or drive it to a tag."
  : "An operator can set its initial pose, or drive it to a tag.";

class FleetDashboard {
  constructor(connection) {
    this.connection = connection;
    this.robots = new Map();
    this.body = document.querySelector("#fleet-table tbody");
  }

  async refresh() {
    try {
      const entries = await api.get(urls.fleet());
      entries.forEach((entry) => this.#merge(entry));
      document.getElementById("fleet-updated").textContent = `updated ${new Date().toLocaleTimeString()}`;
    } catch (error) {
      document.getElementById("fleet-updated").textContent = `fleet state unavailable (${error.message})`;
    }
    this.render();
  }

  #merge(entry) {
    let robot = this.robots.get(entry.robot);
    if (!robot) {
      robot = { name: entry.robot, speed: null, turn: null, nav: null, whereabouts: null, heard: 0 };
      this.robots.set(entry.robot, robot);
      this.#listen(robot);
    }
    Object.assign(robot, { entry, mapId: robot.heard ? robot.mapId : entry.map_id });
  }

  #listen(robot) {
    const ns = `/${robot.name}`;
    const heard = () => { robot.heard = Date.now(); };
    this.connection.subscribe(`${ns}/pose`, "geometry_msgs/PoseStamped", (msg) => {
      heard();
      robot.mapId = msg.header.frame_id;
    }, { throttle_rate: 500, queue_length: 1 });
    this.connection.subscribe(`${ns}/odom`, "nav_msgs/Odometry", (msg) => {
      heard();
      robot.speed = msg.twist.twist.linear.x;
      robot.turn = msg.twist.twist.angular.z;
    }, { throttle_rate: 250, queue_length: 1 });
    this.connection.subscribe(`${ns}/nav_status`, "actionlib_msgs/GoalStatusArray", (msg) => {
      heard();
      robot.nav = msg;
    }, { queue_length: 1 });
    this.connection.subscribe(`${ns}/localisation`, "diagnostic_msgs/DiagnosticStatus", (msg) => {
      heard();
      robot.whereabouts = whereabouts(msg);
    }, { queue_length: 1 });
  }

  online(robot) {
    return heardRecently(robot.heard);
  }

  render() {
    const robots = [...this.robots.values()].sort((a, b) => a.name.localeCompare(b.name));
    this.body.replaceChildren(...robots.map((robot) => this.#row(robot)));
    document.getElementById("fleet-empty").hidden = robots.length > 0;
    this.#stats(robots);
  }

  #row(robot) {
    const online = this.online(robot);
    const [building, map] = splitMapId(robot.mapId);
    const [word, kind, text] = robot.nav ? navigationState(robot.nav) : ["—", "plain", ""];
    const lastSeen = robot.heard ? new Date(robot.heard) : robot.entry?.last_seen;
    const href = `/robots/${encodeURIComponent(robot.name)}/`;
    return el("tr", { class: "clickable", dataset: { robot: robot.name }, onclick: () => { window.location.href = href; } },
      el("td", {}, el("a", { href }, el("strong", {}, robot.name))),
      el("td", {}, badge(online ? "online" : robot.heard ? "silent" : "offline", online ? "ok" : "idle")),
      el("td", {}, building || robot.entry?.buildings.join(", ") || "—"),
      el("td", { class: "submap" }, online ? map || "—" : el("span", { class: "muted", title: "last known" }, map ? `last: ${map}` : "—")),
      el("td", { class: "localisation" }, ...this.#localisation(robot, online)),
      el("td", { class: "num speed" }, online && robot.speed !== null ? `${fixed(robot.speed)} m/s` : "—"),
      el("td", { class: "navigation" }, badge(word, kind), kind === "danger" && text ? el("div", { class: "muted small" }, text) : null),
      el("td", { class: "muted" }, ago(lastSeen)),
    );
  }

  /** Whether the robot knows where it is; a lost one with the way out. */
  #localisation(robot, online) {
    const found = robot.whereabouts;
    if (!online || !found) return ["—"];
    if (found.state !== "lost") return [Object.assign(badge(found.state, found.kind), { title: found.message })];
    return [
      badge("lost, looking for a tag", "warn"),
      el("div", { class: "muted small way-out" }, WAY_OUT),
    ];
  }

  #stats(robots) {
    const online = robots.filter((robot) => this.online(robot));
    const moving = online.filter((r) => Math.abs(r.speed || 0) > 0.01 || Math.abs(r.turn || 0) > 0.01);
    const navigating = online.filter((r) => r.nav && navigationState(r.nav)[0] === "active");
    const lost = online.filter((r) => r.whereabouts?.state === "lost");
    document.getElementById("stat-robots").textContent = robots.length;
    document.getElementById("stat-online").textContent = online.length;
    document.getElementById("stat-moving").textContent = moving.length;
    document.getElementById("stat-navigating").textContent = navigating.length;
    document.getElementById("stat-lost").textContent = lost.length;
  }
}

const dashboard = new FleetDashboard(connectFleet());
const events = new EventsPanel({
  alerts: document.getElementById("alerts-body"),
  alertsEmpty: document.getElementById("alerts-empty"),
  alertsOpen: document.getElementById("alerts-open"),
  events: document.getElementById("events-body"),
  eventsEmpty: document.getElementById("events-empty"),
  mayAcknowledge: ["operator", "admin"].includes(pageConfig().role),
});
dashboard.refresh();
events.refresh();
setInterval(() => {
  dashboard.refresh();
  events.refresh();
}, POLL_MS);
setInterval(() => dashboard.render(), 1000);
