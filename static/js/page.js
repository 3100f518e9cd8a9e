// What every page shares: its configuration, the connection banner, DOM and number helpers.

import { Connection } from "./ros.js";

/** The configuration the server rendered into the page (role, user, subject). */
export function pageConfig() {
  const node = document.getElementById("page-config");
  return node ? JSON.parse(node.textContent) : {};
}

// What every live element says while the page has no connection to the server.
const NOT_LIVE = "Not connected to the server: not live.";

/**
 * Open the page's rosbridge connection and show its state in the top bar, in the banner
 * and on every `.live-element` of the page (greyed, with NOT_LIVE over it).
 */
export function connectFleet() {
  const connection = new Connection();
  const banner = document.getElementById("ws-banner");
  connection.addEventListener("connected", () => {
    banner.hidden = true;
    document.body.classList.remove("server-lost");
    showState();
  });
  connection.addEventListener("disconnected", (event) => {
    banner.hidden = false;
    document.body.classList.add("server-lost");
    sayNotLive();
    const seconds = Math.max(1, Math.round(event.detail.retryInMs / 1000));
    banner.textContent = `Connection to the fleet lost — reconnecting in ${seconds} s…`;
    showState();
  });
  window.cloudnav = { ...(window.cloudnav || {}), connection };
  return connection.start();
}

/**
 * Show in the top bar what the page shows: "Replay" while it replays a recording (the body's
 * `data-mode`), else whether its connection is live.
 */
export function showState() {
  const state = document.getElementById("conn-state");
  const connection = window.cloudnav?.connection;
  if (!state || !connection) return;
  const [text, kind] = document.body.dataset.mode === "replay"
    ? ["Replay", "warn"]
    : connection.connected ? ["Live", "ok"] : ["Offline", "danger"];
  state.hidden = false;
  state.replaceChildren(badge(text, kind));
}

/**
 * STOP (`/cloudnav/stop`): the server halts `robot` whatever moves it (zero velocity, its
 * goal cancelled whoever sent it, its mission paused, another operator's teleop lock
 * withdrawn) and says what it did; resolves to that sentence.
 */
export async function stopRobot(connection, robot) {
  const answer = await connection.call("/cloudnav/stop", "cloudnav/Stop", { robot });
  return answer.message;
}

/**
 * Where the server would put a goal or an initial pose (`what`) pressed at `pose` of
 * sub-map `mapId` for `robot` (`/cloudnav/check_pose`): `{ refusal, pose, note }`.
 * `refusal` says why it would refuse it (in an obstacle, in unknown space, outside the map,
 * out of reach, or, by the building's fleet rule, a spot another robot holds), "" if it
 * takes it; `pose` is where it goes (moved to the nearest free spot when another robot
 * holds the one pressed) and `note` says so. The server checks what is published anyway.
 */
export async function placePose(connection, mapId, pose, robot, what = "goal") {
  const args = { map_id: mapId, x: pose.x, y: pose.y, what, robot };
  try {
    const answer = await connection.call("/cloudnav/check_pose", "cloudnav/CheckPose", args);
    if (!answer.success) return { refusal: answer.message, pose, note: "" };
    const moved = typeof answer.x === "number" && typeof answer.y === "number";
    return { refusal: "", pose: moved ? { ...pose, x: answer.x, y: answer.y } : pose, note: answer.message || "" };
  } catch {
    return { refusal: "", pose, note: "" }; // the publication is checked where it arrives
  }
}

/** Give each live element its note; CSS shows the notes while the body is `server-lost`. */
function sayNotLive() {
  for (const element of document.querySelectorAll(".live-element")) {
    if (!element.querySelector(":scope > .live-lost")) element.append(el("div", { class: "live-lost", role: "status" }, NOT_LIVE));
  }
}

/** Create an element: `el("td", {class: "num"}, "3.2")`. */
export function el(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attributes)) {
    if (value === null || value === undefined || value === false) continue;
    if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
    else if (key === "dataset") Object.assign(node.dataset, value);
    else node.setAttribute(key, value === true ? "" : value);
  }
  node.append(...children.filter((child) => child !== null && child !== undefined));
  return node;
}

/**
 * Ask a person to confirm something with consequences, in a modal <dialog>: `title`, then
 * `text` and `lines` (a list), then buttons `cancel` (the default: Escape and the form's
 * first button) and `confirm`; `fields` (elements, e.g. a note to fill in) go above the
 * buttons. Resolves to true only when they confirm.
 */
export function askToConfirm({ title, text = "", lines = [], confirm = "Continue", cancel = "Cancel", id = "", fields = [] }) {
  const dialog = el("dialog", { class: "confirm", id: id || null, "aria-label": title },
    el("form", { method: "dialog" },
      el("h2", {}, title),
      text ? el("p", {}, text) : null,
      lines.length ? el("ul", {}, ...lines.map((line) => el("li", {}, line))) : null,
      ...fields,
      el("div", { class: "row" },
        el("button", { class: "btn", value: "cancel", autofocus: true }, cancel),
        el("button", { class: "btn primary", value: "confirm" }, confirm))));
  document.body.append(dialog);
  return new Promise((resolve) => {
    dialog.addEventListener("close", () => {
      resolve(dialog.returnValue === "confirm");
      dialog.remove();
    }, { once: true });
    dialog.showModal();
  });
}

export function badge(text, kind = "") {
  return el("span", { class: `badge ${kind}` }, text);
}

export function fixed(value, digits = 2) {
  return Number.isFinite(value) ? value.toFixed(digits) : "—";
}

export function formatBytes(bytesPerUnit) {
  if (!Number.isFinite(bytesPerUnit)) return "—";
  if (bytesPerUnit >= 1e6) return `${(bytesPerUnit / 1e6).toFixed(2)} MB`;
  if (bytesPerUnit >= 1e3) return `${(bytesPerUnit / 1e3).toFixed(1)} kB`;
  return `${Math.round(bytesPerUnit)} B`;
}

/** "3 s ago", "5 min ago" from a Date or ISO string; "never" for none. */
export function ago(when, now = Date.now()) {
  if (!when) return "never";
  const seconds = Math.max(0, (now - new Date(when).getTime()) / 1000);
  if (seconds < 2) return "just now";
  if (seconds < 90) return `${Math.round(seconds)} s ago`;
  if (seconds < 5400) return `${Math.round(seconds / 60)} min ago`;
  if (seconds < 129600) return `${Math.round(seconds / 3600)} h ago`;
  return new Date(when).toLocaleString();
}

/** Goal status (actionlib_msgs/GoalStatus) as a word and a badge kind. */
const GOAL_STATUS = [
  ["pending", "info"], ["active", "info"], ["preempted", "warn"], ["succeeded", "ok"],
  ["aborted", "danger"], ["rejected", "danger"], ["preempting", "warn"], ["recalling", "warn"],
  ["recalled", "warn"], ["lost", "danger"],
];

export function goalStatus(code) {
  return GOAL_STATUS[code] || ["unknown", ""];
}

/**
 * A robot's `localisation` (diagnostic_msgs/DiagnosticStatus) as {state, message, mapId,
 * source, kind}: state is lost, entering or localised; kind a badge kind.
 */
export function whereabouts(status) {
  const values = Object.fromEntries((status?.values || []).map(({ key, value }) => [key, value]));
  const state = values.state || "unknown";
  const kind = state === "localised" ? "ok" : state === "lost" ? "warn" : "info";
  return { state, message: status?.message || state, mapId: values.map_id || "", source: values.source || "", kind };
}

/** The latest entry of a GoalStatusArray as [word, kind, text], or idle when empty. */
export function navigationState(statusArray) {
  const list = statusArray?.status_list || [];
  if (!list.length) return ["idle", "idle", ""];
  const latest = list[list.length - 1];
  const [word, kind] = goalStatus(latest.status);
  return [word, kind, latest.text || ""];
}
