// The robot page's mapping card: start a mapping session for this robot (a new sub-map,
// or a new version of one), watch the map grow with the corrected path, then finish,
// resume, discard or (admins) publish it. The server tells the page when the session
// changes or saves its map (the robot's latched `mapping` topic); the page reads it then,
// and once every SLOW_MS for what no mapping worker tells (a finished session published
// or discarded from another page). A visual session's 3D map is drawn beside the grid
// (map3d.js), fed the new keyframes' points each time the session saves.

import { ApiError, api } from "./api.js";
import { CloudView } from "./map3d.js";
import { MapView } from "./mapview.js";
import { askToConfirm, el, fixed, pageConfig } from "./page.js";

const $ = (id) => document.getElementById(id);
const SLOW_MS = 30000;
const OPEN = ["running", "interrupted"];
const config = pageConfig();
const card = $("mapping-card");
const sessionsUrl = "/api/mapping/sessions/";
const state = { session: null, snapshot: 0 };
const view = new MapView($("mapping-canvas"));
let cloud = null; // the 3D view, made for the first visual session (a WebGL context)
window.cloudnav = { ...(window.cloudnav || {}), mapping: { view, state, cloud: () => cloud } };

async function refresh() {
  try {
    const list = await api.get(`${sessionsUrl}?robot=${encodeURIComponent(config.robot)}`);
    state.session = list.find((s) => OPEN.includes(s.state)) || list.find((s) => s.state === "finished") || null;
    await show(state.session);
  } catch (error) {
    say("error", error.message);
  }
}

async function show(session) {
  $("mapping-state").textContent = session ? `${session.map_id}: ${session.state}` : "no session";
  card.dataset.state = session ? session.state : "";
  for (const [id, states] of [["finish", OPEN], ["resume", ["interrupted"]], ["discard", [...OPEN, "finished"]], ["publish", ["finished"]]]) {
    const button = $(`mapping-${id}`);
    if (button) button.hidden = !session || !states.includes(session.state) || (id === "publish" && config.role !== "admin");
  }
  const start = $("mapping-start");
  if (start) start.hidden = Boolean(session && OPEN.includes(session.state));
  if (!session) return;
  const s = session.stats || {};
  const visual = session.kind === "visual";
  const dropped = `${s.dropped ?? 0} ${visual ? "frames" : "scans"} dropped`;
  const lost = visual
    ? ` · ${s.lost ?? 0} frames lost · ${s.restarted ?? 0} restarts from odometry · ${s.refused ?? 0} refused`
    : "";
  $("mapping-figures").textContent = session.snapshot
    ? `${session.size[0]}×${session.size[1]} cells · ${s.keyframes ?? 0} keyframes · ${s.loop_closures ?? 0} loop closures · ${dropped}${lost} · ${fixed(100 * (s.cpu_share ?? 0), 1)} % CPU`
    : `waiting for the robot's ${visual ? "camera" : "scans"}…`;
  if (session.reason) say("info", session.reason);
  if (session.snapshot && session.snapshot !== state.snapshot) {
    view.setGrid(await api.get(`${sessionsUrl}${session.id}/grid`));
    state.snapshot = session.snapshot;
    $("mapping-wrap").dataset.snapshot = session.snapshot;
  }
  $("mapping-3d-wrap").hidden = !visual;
  if (visual && session.snapshot) await show3d(session);
  view.set("trail", (session.path || []).map(([x, y]) => ({ x, y })));
  const last = (session.path || []).at(-1);
  view.set("robot", last ? { x: last[0], y: last[1], yaw: last[2] } : null);
}

async function show3d(session) {
  try {
    cloud = cloud || new CloudView($("mapping-3d"));
    await cloud.update(session.id);
  } catch (error) {
    say("error", `3D view: ${error.message}`);
  }
}

function say(kind, text) {
  $("mapping-messages").replaceChildren(...(text ? [el("div", { class: `alert ${kind}`, role: "status" }, text)] : []));
}

async function act(action, body = undefined) {
  if (!state.session) return;
  try {
    const answer = await api.post(`${sessionsUrl}${state.session.id}/${action}`, body);
    if (action === "publish") say("ok", `Published as v${answer.number} of ${state.session.map_id}.`);
    else say("", "");
    await refresh();
  } catch (error) {
    say("error", error instanceof ApiError ? error.messages.join("; ") : error.message);
  }
}

/** Publishing makes a new version robots take up: asked first, with a note for its history. */
async function publish() {
  if (!state.session) return;
  const note = el("textarea", { name: "note", rows: 2, maxlength: 500, placeholder: "what was mapped, and why" });
  const sure = await askToConfirm({
    id: "mapping-publish-dialog",
    title: `Publish ${state.session.map_id}?`,
    text: "The map becomes a new version of the sub-map; robots entering it take it up.",
    fields: [el("label", { class: "field" }, "Note (kept in the version's history)", note)],
    confirm: "Publish",
  });
  if (sure) await act("publish", { note: note.value.trim() });
}

async function start(event) {
  event.preventDefault();
  const form = event.target;
  try {
    await api.post(sessionsUrl, {
      robot: config.robot,
      building: config.buildings[0],
      code: form.code.value,
      update: form.update.value === "true",
      kind: form.kind.value,
    });
    state.snapshot = 0;
    say("ok", "Mapping: drive the robot around; the map grows here.");
    await refresh();
  } catch (error) {
    say("error", error instanceof ApiError ? error.messages.join("; ") : error.message);
  }
}

if (card.dataset.mayDrive === "1") {
  $("mapping-start").addEventListener("submit", start);
  for (const action of ["finish", "resume", "discard", "publish"]) {
    $(`mapping-${action}`).addEventListener("click", () => (action === "publish" ? publish() : act(action)));
  }
}
refresh();
setInterval(refresh, SLOW_MS);

let refreshing = false;
let again = false;
/** Read the session again when the server says it changed (`connection`: the page's rosbridge). */
export function followSessions(connection) {
  connection.subscribe(`/${config.robot}/mapping`, "std_msgs/String", refreshOnce);
}

/** One read at a time; news during a read asks for one more after it. */
async function refreshOnce() {
  again = refreshing;
  if (refreshing) return;
  refreshing = true;
  try {
    do {
      again = false;
      await refresh();
    } while (again);
  } finally {
    refreshing = false;
  }
}
