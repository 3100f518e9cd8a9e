// A building's page: its topology (edited by admins and saved whole, with the server's
// validation shown), routes between sub-maps drawn on it, and the robots in it, live: a
// robot is online, and on the sub-map it says, only while this page hears from it.

import { ApiError, api, splitMapId, urls } from "./api.js";
import { heardRecently, liveness } from "./liveness.js";
import { MembersPanel } from "./members.js";
import { RecordingPanel } from "./recording.js";
import { askToConfirm, badge, connectFleet, el, pageConfig } from "./page.js";
import { TopologyView, edgeKey } from "./topology.js";

// The registered robots are asked for this often; their state comes over rosbridge.
const FLEET_MS = 5000;
const RENDER_MS = 1000;
const CHECK_DELAY_MS = 300;
const $ = (id) => document.getElementById(id);
const config = pageConfig();
const building = config.building;
const editable = config.role === "admin";
const view = new TopologyView($("topology"), { editable });
let saved = null;

async function loadTopology() {
  saved = await api.get(urls.topology(building));
  view.load(saved);
  markDirty(false);
  await Promise.all([showValidation(), showRoute()]);
}

/** The tag coverage of the saved graph, or of `proposal` (a graph being edited, not saved). */
async function showValidation(proposal = null) {
  const report = proposal ? await api.post(urls.validation(building), proposal) : await api.get(urls.validation(building));
  view.setInvalid(report.uncrossable_edges.map((edge) => edgeKey(edge.from, edge.to)));
  const box = $("topology-validation");
  box.dataset.state = report.valid ? "valid" : "uncovered";
  if (report.valid) {
    box.replaceChildren(el("div", { class: "alert ok" }, "Every edge has tags both ways, and every tag links along an edge."));
    return report;
  }
  const lines = [
    ...report.uncrossable_edges.map(uncrossable),
    ...report.dangling_tags.map((tag) => `Tag #${tag.marker_id} in ${tag.map} links to ${tag.links_to} along no edge.`),
  ];
  const kind = report.uncrossable_edges.length ? "warn" : "info";
  const title = proposal ? "Not saved yet — coverage of this graph" : "Coverage";
  box.replaceChildren(el("div", { class: `alert ${kind}` }, el("strong", {}, title), el("ul", {}, ...lines.map((line) => el("li", {}, line))),
    report.uncrossable_edges.length ? el("div", {}, "Robots are never routed across these until a tag is placed there.") : null));
  return report;
}

function uncrossable(edge) {
  return `No tag lets a robot cross ${edge.from} → ${edge.to}.`;
}

let checking = null;
/** Check the graph being edited, a moment after the last change. */
function checkSoon() {
  clearTimeout(checking);
  checking = setTimeout(() => showValidation(view.document()).catch(() => {}), CHECK_DELAY_MS);
}

let routeAsked = 0;
async function showRoute() {
  const from = $("route-from").value;
  const to = $("route-to").value;
  const list = $("route-steps");
  if (!from || !to) return;
  const asked = ++routeAsked; // answers can come back out of order: show the last asked
  try {
    const route = await api.get(urls.route(building, from, to));
    if (asked !== routeAsked) return;
    view.setRoute(route.steps.map((step) => step.map));
    list.replaceChildren(...route.steps.map((step) => el("li", { "data-map": step.map },
      step.map, step.tag ? el("span", { class: "muted" }, ` — tag #${step.tag.marker_id}`) : null)));
  } catch (error) {
    if (asked !== routeAsked) return;
    view.setRoute([]);
    list.replaceChildren(el("li", { class: "muted" }, `No route: ${error.message}`));
  }
}

function message(kind, title, lines = []) {
  const box = $("topology-messages");
  if (!title) {
    box.replaceChildren();
    return;
  }
  box.replaceChildren(el("div", { class: `alert ${kind}`, role: "status" }, el("strong", {}, title),
    lines.length ? el("ul", {}, ...lines.map((line) => el("li", {}, line))) : null));
}

function markDirty(dirty) {
  if (!editable) return;
  $("topology-save").disabled = !dirty;
  $("topology-revert").disabled = !dirty;
}

/** Whether to save a graph whose `uncrossable` edge directions no robot can cross. */
function confirmUncrossable(edges) {
  return askToConfirm({
    id: "uncrossable-dialog",
    title: "Save edges no robot can cross?",
    text: "No tag stands where these edges cross, so robots will not be routed along them until tags are placed:",
    lines: edges.map((edge) => `${edge.from} → ${edge.to}`),
    confirm: "Save anyway",
    cancel: "Keep editing",
  });
}

async function save() {
  const proposal = view.document();
  try {
    const report = await showValidation(proposal);
    if (report.uncrossable_edges.length && !(await confirmUncrossable(report.uncrossable_edges))) {
      message("info", "Not saved: the graph is as you left it.");
      return;
    }
    saved = await api.put(urls.topology(building), proposal);
    view.load(saved);
    markDirty(false);
    message("ok", "Topology saved.");
    await Promise.all([showValidation(), showRoute()]);
  } catch (error) {
    const lines = error instanceof ApiError ? error.messages : [error.message];
    message("error", "The server refused this topology:", lines);
  }
}

function showEdgeEditor() {
  const edge = view.selectedEdge();
  $("edge-editor").hidden = !edge;
  if (!edge) return;
  $("edge-name").textContent = `${edge.a} ↔ ${edge.b}`;
  $("edge-cost").value = edge.cost;
}

function bindEditor() {
  view.addEventListener("change", () => {
    markDirty(true);
    message("", "");
    showEdgeEditor();
    checkSoon();
  });
  view.addEventListener("select", showEdgeEditor);
  $("edge-cost").addEventListener("input", (event) => {
    const cost = Number(event.target.value);
    if (event.target.value !== "" && Number.isFinite(cost)) view.setCost(cost);
  });
  $("edge-remove").addEventListener("click", () => view.removeSelected());
  $("topology-save").addEventListener("click", save);
  $("topology-revert").addEventListener("click", () => {
    view.load(saved);
    markDirty(false);
    message("", "");
    showEdgeEditor();
    showValidation();
    showRoute();
  });
}

// ------------------------------------------------------------ the robots, live

const connection = connectFleet();
// Robot name -> {name, heard, mapId, lastMapId}: mapId is what it said while live;
// lastMapId the server's record, shown as "last" and never as where it is.
const robots = new Map();
let drawnRobots = "";

async function refreshRobots() {
  const entries = await api.get(`${urls.fleet()}?building=${encodeURIComponent(building)}`).catch(() => null);
  if (!entries) return;
  for (const entry of entries) {
    if (!robots.has(entry.robot)) listen({ name: entry.robot, heard: 0, mapId: "" });
    robots.get(entry.robot).lastMapId = entry.map_id;
  }
  renderRobots();
}

function listen(robot) {
  robots.set(robot.name, robot);
  const ns = `/${robot.name}`;
  const heard = () => { robot.heard = Date.now(); };
  connection.subscribe(`${ns}/pose`, "geometry_msgs/PoseStamped", (msg) => {
    heard();
    robot.mapId = msg.header.frame_id;
  }, { throttle_rate: 1000, queue_length: 1 });
  connection.subscribe(`${ns}/localisation`, "diagnostic_msgs/DiagnosticStatus", (msg) => {
    heard();
    if (msg.values?.find((value) => value.key === "state")?.value === "lost") robot.mapId = "";
  }, { queue_length: 1 });
  connection.subscribe(`${ns}/nav_status`, "actionlib_msgs/GoalStatusArray", heard, { queue_length: 1 });
}

function renderRobots() {
  const now = Date.now();
  const live = [...robots.values()].filter((robot) => heardRecently(robot.heard, now));
  const onNodes = new Map();
  for (const robot of live) {
    const [home, map] = splitMapId(robot.mapId);
    if (home === building) onNodes.set(map, [...(onNodes.get(map) || []), robot.name]);
  }
  // Drawn again only when it changes: an admin may be dragging a node.
  const drawn = JSON.stringify([...onNodes]);
  if (drawn !== drawnRobots) view.setRobots(onNodes);
  drawnRobots = drawn;
  const rows = [...robots.values()].sort((a, b) => a.name.localeCompare(b.name, undefined, { numeric: true }));
  $("building-robots").replaceChildren(...(rows.length ? rows.map((robot) => robotRow(robot, now)) : [el("tr", {}, el("td", { class: "muted" }, "No robots registered here."))]));
}

function robotRow(robot, now) {
  const [word, kind] = liveness(robot.heard, "offline", now);
  const live = kind === "ok";
  const last = splitMapId(robot.lastMapId || robot.mapId)[1];
  return el("tr", { dataset: { robot: robot.name, state: word } },
    el("td", {}, el("a", { href: `/robots/${robot.name}/` }, el("strong", {}, robot.name))),
    el("td", {}, badge(word, kind)),
    el("td", { class: "mono muted submap" }, live ? splitMapId(robot.mapId)[1] || "—" : last ? `last: ${last}` : "—"));
}

for (const row of document.querySelectorAll("tr[data-href]")) {
  row.addEventListener("click", () => { window.location.href = row.dataset.href; });
}
$("route-from").addEventListener("change", showRoute);
$("route-to").addEventListener("change", showRoute);
if (editable) {
  bindEditor();
  new MembersPanel(building).load();
}
new RecordingPanel(building, { editable }).load();
window.cloudnav = { ...(window.cloudnav || {}), topology: view };
loadTopology();
refreshRobots();
setInterval(refreshRobots, FLEET_MS);
setInterval(renderRobots, RENDER_MS);
