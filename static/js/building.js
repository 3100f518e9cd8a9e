// A building's page: its topology (edited by admins and saved whole, with the server's
// validation shown), routes between sub-maps drawn on it, and the robots in it.

import { ApiError, api, splitMapId, urls } from "./api.js";
import { askToConfirm, badge, el, pageConfig } from "./page.js";
import { TopologyView, edgeKey } from "./topology.js";

const ROBOTS_MS = 3000;
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

async function showRobots() {
  const entries = await api.get(`${urls.fleet()}?building=${encodeURIComponent(building)}`).catch(() => []);
  const onNodes = new Map();
  for (const entry of entries.filter((e) => e.online)) {
    const [home, map] = splitMapId(entry.map_id);
    if (home === building) onNodes.set(map, [...(onNodes.get(map) || []), entry.robot]);
  }
  view.setRobots(onNodes);
  $("building-robots").replaceChildren(...(entries.length ? entries.map(robotRow) : [el("tr", {}, el("td", { class: "muted" }, "No robots registered here."))]));
}

function robotRow(entry) {
  return el("tr", {},
    el("td", {}, el("a", { href: `/robots/${entry.robot}/` }, el("strong", {}, entry.robot))),
    el("td", {}, badge(entry.online ? "online" : "offline", entry.online ? "ok" : "idle")),
    el("td", { class: "mono muted" }, splitMapId(entry.map_id)[1] || "—"));
}

for (const row of document.querySelectorAll("tr[data-href]")) {
  row.addEventListener("click", () => { window.location.href = row.dataset.href; });
}
$("route-from").addEventListener("change", showRoute);
$("route-to").addEventListener("change", showRoute);
if (editable) bindEditor();
window.cloudnav = { ...(window.cloudnav || {}), topology: view };
loadTopology();
showRobots();
setInterval(showRobots, ROBOTS_MS);
