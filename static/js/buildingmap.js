// A building's live map: every sub-map as one floor plan, every robot of the building on
// it (pose, heading, trail, plan, goal and its route across sub-maps), its state in the
// list beside; click a robot to select it, then follow or open it; operators choose Goal
// and press and drag anywhere on the plan: the sub-map under the pointer is the goal's frame.

import { api, splitMapId, urls } from "./api.js";
import { FloorPlan, LAYERS } from "./floorplan.js";
import { planarPose, poseStamped } from "./geometry.js";
import { heardRecently, liveness } from "./liveness.js";
import { MissionsPanel } from "./missions.js";
import { ParkingSpots } from "./parking.js";
import { badge, connectFleet, el, navigationState, pageConfig, placePose, stopRobot, whereabouts } from "./page.js";

const TRAIL_POINTS = 300;
const TRAIL_STEP_M = 0.05;
const FLEET_MS = 5000;
// nav_status codes after which a goal is over (actionlib_msgs/GoalStatus).
const FINISHED = new Set([2, 3, 4, 5, 8, 9]);
// A goal just sent is not ended by the status of the one before it.
const GOAL_GRACE_MS = 1500;
// The cloud's planner (the robots' own A*), for the legs of a route in other sub-maps.
const PLAN_PATH = "/cloudnav/plan_path";
const PLAN_PATH_TYPE = "cloudnav/PlanPath";
const $ = (id) => document.getElementById(id);

const config = pageConfig();
const building = config.building;
const mayDrive = ["operator", "admin"].includes(config.role);
const mayEdit = config.role === "admin";
const connection = connectFleet();
const plan = new FloorPlan($("floor-plan"));
const wrap = $("floor-plan");
let following = false;
window.cloudnav.floorPlan = plan;

/** What the page knows of one robot, all in the building frame. */
function newTrack(name) {
  return {
    name, pose: null, map: null, heard: 0, live: false, trail: [], plan: [], goal: null,
    route: [], nav: null, whereabouts: null, elsewhere: null, giveWay: null,
  };
}

// ------------------------------------------------------------ loading

async function loadBuilding() {
  const [submaps, tags] = await Promise.all([api.get(urls.submaps(building)), api.get(urls.tags(building))]);
  plan.setTags(tags);
  // Grids are heavy answers, a few at a time per client: one after the other, each shown
  // as it comes.
  for (const [index, submap] of submaps.entries()) {
    plan.addSubmap(submap.code, await heavy(() => api.get(urls.grid(building, submap.code))));
    if (index === 0) plan.fit();
  }
  plan.fit();
  wrap.dataset.loaded = submaps.map((s) => s.code).join(",");
}

/** A heavy answer, asked again while the server says it is busy (429, 503). */
async function heavy(ask, tries = 8) {
  for (let attempt = 1; ; attempt += 1) {
    try {
      return await ask();
    } catch (error) {
      if (attempt >= tries || ![429, 503].includes(error.status)) throw error;
      await new Promise((resolve) => setTimeout(resolve, 250 * attempt));
    }
  }
}

async function refreshFleet() {
  const entries = await api.get(`${urls.fleet()}?building=${encodeURIComponent(building)}`).catch(() => null);
  if (!entries) return;
  for (const entry of entries) {
    if (!plan.robots.has(entry.robot)) listen(entry.robot);
  }
  renderList();
}

// ------------------------------------------------------------ live topics

function listen(name) {
  const track = newTrack(name);
  plan.robots.set(name, track);
  const ns = `/${name}`;
  const heard = () => { track.heard = Date.now(); };
  connection.subscribe(`${ns}/pose`, "geometry_msgs/PoseStamped", (msg) => {
    heard();
    onPose(track, msg);
  }, { queue_length: 1 });
  connection.subscribe(`${ns}/map_id`, "std_msgs/String", (msg) => {
    heard();
    enter(track, msg.data);
  });
  connection.subscribe(`${ns}/plan`, "nav_msgs/Path", (msg) => {
    const [home] = splitMapId(msg.header.frame_id);
    track.plan = home === building ? msg.poses.map((p) => ({ x: p.pose.position.x, y: p.pose.position.y })) : [];
    plan.changed();
  }, { throttle_rate: 250, queue_length: 1 });
  connection.subscribe(`${ns}/goal`, "geometry_msgs/PoseStamped", (msg) => {
    setGoal(track, msg.header.frame_id, planarPose(msg.pose));
  }, { queue_length: 1 });
  connection.subscribe(`${ns}/nav_status`, "actionlib_msgs/GoalStatusArray", (msg) => {
    heard();
    onStatus(track, msg);
  }, { queue_length: 1 });
  connection.subscribe(`${ns}/right_of_way`, "std_msgs/String", (msg) => {
    track.giveWay = giveWayOf(msg.data);
    plan.changed();
    renderList();
  });
  connection.subscribe(`${ns}/localisation`, "diagnostic_msgs/DiagnosticStatus", (msg) => {
    heard();
    track.whereabouts = whereabouts(msg);
    if (track.whereabouts.state === "lost") track.pose = null;
    plan.changed();
  }, { queue_length: 1 });
}

/**
 * The cloud's right of way for a robot (``/r/right_of_way``): null when it may go, else
 * where it waits ({spot, place, waitingFor, message}, in the building frame).
 */
function giveWayOf(data) {
  let order;
  try {
    order = JSON.parse(data);
  } catch {
    return null;
  }
  if (order?.state !== "wait" || splitMapId(order.map_id)[0] !== building) return null;
  const [x, y, yaw] = order.spot;
  return { spot: { x, y, yaw }, place: { x: order.place[0], y: order.place[1] }, waitingFor: order.waiting_for, message: order.message };
}

function onPose(track, msg) {
  enter(track, msg.header.frame_id);
  if (track.elsewhere) return;
  track.pose = planarPose(msg.pose);
  track.live = true;
  const last = track.trail[track.trail.length - 1];
  if (!last || Math.hypot(last.x - track.pose.x, last.y - track.pose.y) > TRAIL_STEP_M) {
    track.trail.push({ x: track.pose.x, y: track.pose.y });
    if (track.trail.length > TRAIL_POINTS) track.trail.shift();
  }
  if (following && plan.selected === track.name) plan.centerOn(track.pose.x, track.pose.y);
  plan.changed();
}

/** The robot is in sub-map `mapId` now; one in another building is not drawn here. */
function enter(track, mapId) {
  const [home, map] = splitMapId(mapId);
  track.elsewhere = home && home !== building ? home : null;
  if (track.elsewhere) track.pose = null;
  if (!map || map === track.map) return;
  track.map = home === building ? map : null;
  routeOf(track);
}

function setGoal(track, mapId, pose) {
  const [home, map] = splitMapId(mapId);
  track.goal = home === building ? { map, pose, at: Date.now() } : null;
  routeOf(track);
  plan.changed();
}

function onStatus(track, msg) {
  track.nav = msg;
  const list = msg.status_list || [];
  const latest = list[list.length - 1];
  const over = !latest || FINISHED.has(latest.status);
  if (track.goal && over && Date.now() - track.goal.at > GOAL_GRACE_MS) {
    track.goal = null;
    track.route = [];
    plan.changed();
  }
}

/**
 * A robot's way to a goal in another sub-map: through the tags it drives to (straight at
 * first), then along the paths the cloud's planner finds in each sub-map of the route.
 */
async function routeOf(track) {
  const goal = track.goal;
  if (!goal || !track.map || goal.map === track.map) {
    track.route = [];
    return;
  }
  try {
    const answer = await api.get(urls.route(building, track.map, goal.map));
    if (track.goal !== goal) return;
    track.route = answer.steps.filter((step) => step.tag).map((step) => ({ x: step.tag.x, y: step.tag.y }));
    plan.changed();
    const planned = await plannedRoute(answer.steps, track.pose, goal.pose);
    if (track.goal === goal) track.route = planned;
  } catch {
    track.route = [];
  }
  plan.changed();
}

/** The route's legs, planned in their sub-maps: from `start` (or the first tag when the
 * robot's pose is unknown) through each step's tag to `end`. */
async function plannedRoute(steps, start, end) {
  const legs = [];
  let from = start;
  for (const step of steps) {
    const to = step.tag ? { x: step.tag.x, y: step.tag.y } : end;
    if (from) legs.push(leg(step.map_id, from, to));
    from = to;
  }
  return (await Promise.all(legs)).flat();
}

/** The planner's path from `from` to `to` in sub-map `mapId`, or the straight line. */
async function leg(mapId, from, to) {
  try {
    const answer = await connection.call(PLAN_PATH, PLAN_PATH_TYPE, {
      map_id: mapId, start: { x: from.x, y: from.y }, goal: { x: to.x, y: to.y },
    });
    return answer.path.poses.map((p) => ({ x: p.pose.position.x, y: p.pose.position.y }));
  } catch {
    return [from, to];
  }
}

// ------------------------------------------------------------ the list and the selection

function stateOf(track) {
  if (!track.live) return liveness(track.heard);
  if (track.elsewhere) return [`in ${track.elsewhere}`, "plain"];
  if (track.whereabouts?.state === "lost") return ["lost", "warn"];
  if (track.giveWay) return [`waits for ${track.giveWay.waitingFor}`, "warn"];
  if ([...plan.robots.values()].some((t) => t.giveWay?.waitingFor === track.name)) return ["right of way", "ok"];
  return ["online", "ok"];
}

function renderList() {
  const tracks = [...plan.robots.values()].sort((a, b) => a.name.localeCompare(b.name, undefined, { numeric: true }));
  $("robot-list").replaceChildren(...tracks.map(robotRow));
  $("robot-list-empty").hidden = tracks.length > 0;
  renderSelected();
}

function robotRow(track) {
  const [word, kind] = stateOf(track);
  const [nav, navKind] = track.nav ? navigationState(track.nav) : ["—", "plain"];
  return el("tr", {
    class: `clickable ${plan.selected === track.name ? "selected" : ""}`,
    dataset: { robot: track.name, state: word },
    onclick: () => plan.select(track.name),
  },
  el("td", {}, el("strong", {}, track.name)),
  el("td", {}, badge(word, kind)),
  el("td", { class: "mono muted submap" }, track.live ? track.map || "—" : "—"),
  el("td", {}, badge(nav, navKind)));
}

function renderSelected() {
  const track = plan.robots.get(plan.selected);
  $("selected-card").hidden = !track;
  if (!track) return;
  const [word, kind] = stateOf(track);
  $("selected-name").textContent = track.name;
  $("selected-state").replaceChildren(badge(word, kind));
  $("selected-map").textContent = track.live && track.map ? track.map : "—";
  $("selected-way").textContent = track.giveWay ? track.giveWay.message : "—";
  $("selected-goal").textContent = track.goal ? `${track.goal.map} · ${track.goal.pose.x.toFixed(2)}, ${track.goal.pose.y.toFixed(2)}` : "none";
  $("selected-open").href = `/robots/${encodeURIComponent(track.name)}/`;
  $("selected-follow").classList.toggle("active", following);
}

/** Live means heard from in the last few seconds: checked twice a second. */
function ageTracks() {
  const now = Date.now();
  for (const track of plan.robots.values()) {
    const live = heardRecently(track.heard, now);
    if (live !== track.live) {
      track.live = live;
      plan.changed();
    }
  }
  wrap.dataset.live = [...plan.robots.values()].filter((t) => t.live && t.pose).map((t) => t.name).join(",");
  renderList();
}

// ------------------------------------------------------------ goals

function selectTool(tool) {
  const next = plan.tool === tool ? null : tool;
  if (next === "goal" && !plan.selected) {
    hint("Click a robot on the plan (or in the list) first: the goal is for it.");
    return;
  }
  plan.setTool(next);
  $("tool-goal")?.classList.toggle("active", next === "goal");
  $("tool-parking")?.classList.toggle("active", next === "parking");
  if (next === "parking") hint("Tap the plan where robots may wait (drag for its heading).");
  else hint(next ? `Press where ${plan.selected} should go and drag towards its heading.` : "");
}

function hint(text) {
  $("plan-hint").hidden = !text;
  $("plan-hint").textContent = text;
}

async function sendGoal({ pose, map }) {
  const name = plan.selected;
  selectTool(null);
  if (!map) {
    hint("That point is outside every sub-map: no goal sent.");
    return;
  }
  const mapId = `${building}/${map}`;
  const placed = await placePose(connection, mapId, pose, name);
  if (placed.refusal) {
    hint(`No goal sent: ${placed.refusal}`);
    wrap.dataset.refused = `${name}:${mapId}`;
    return;
  }
  if (!connection.publish(`/${name}/goal`, "geometry_msgs/PoseStamped", poseStamped(mapId, placed.pose))) {
    hint("Not connected to the server: no goal sent.");
    return;
  }
  setGoal(plan.robots.get(name), mapId, placed.pose);
  hint(placed.note ? `Goal sent to ${name} in ${map}. ${placed.note}` : `Goal sent to ${name} in ${map}.`);
  if (placed.note) wrap.dataset.moved = `${name}:${mapId}`;
  else delete wrap.dataset.moved;
  wrap.dataset.goal = `${name}:${mapId}`;
}

/** STOP the selected robot: the server halts it whatever moves it. */
async function stopSelected() {
  const name = plan.selected;
  if (!name) return;
  try {
    hint(`${name} stopped: ${await stopRobot(connection, name)}`);
  } catch (error) {
    hint(`STOP of ${name} failed: ${error.message}`);
  }
}

// ------------------------------------------------------------ controls

function bindControls() {
  plan.addEventListener("select", () => {
    following = following && Boolean(plan.selected);
    renderList();
  });
  plan.addEventListener("pose", (event) => {
    if (event.detail.tool === "goal") sendGoal(event.detail);
    if (event.detail.tool === "parking") {
      selectTool(null);
      parking.place(event.detail);
    }
  });
  plan.addEventListener("hover", ({ detail }) => {
    $("plan-cursor").textContent = `${detail.x.toFixed(2)}, ${detail.y.toFixed(2)} m${detail.map ? ` · ${detail.map}` : ""}`;
  });
  $("plan-fit").addEventListener("click", () => plan.fit());
  $("selected-follow").addEventListener("click", () => {
    following = !following;
    const track = plan.robots.get(plan.selected);
    if (following && track?.pose) plan.centerOn(track.pose.x, track.pose.y);
    renderSelected();
  });
  if (mayDrive) {
    $("tool-goal").addEventListener("click", () => selectTool("goal"));
    $("selected-stop").addEventListener("click", () => stopSelected());
  }
  if (mayEdit) $("tool-parking").addEventListener("click", () => selectTool("parking"));
  for (const [key, title] of Object.entries(LAYERS)) {
    const box = el("input", { type: "checkbox", checked: true, dataset: { layer: key } });
    box.addEventListener("change", () => plan.setLayer(key, box.checked));
    $("layers").append(el("label", { class: "layer" }, box, title));
  }
  document.addEventListener("keydown", (event) => {
    if (event.key === "Escape" && plan.tool) selectTool(null);
  });
}

const parking = new ParkingSpots({
  plan, building, editable: mayEdit, list: $("parking-list"), empty: $("parking-empty"), hint,
});
bindControls();
new MissionsPanel({ building, plan, connection, mayDrive, hint }).start();
loadBuilding().catch((error) => hint(`Cannot load the building: ${error.message}`));
parking.load().catch((error) => hint(`Cannot load the parking spots: ${error.message}`));
refreshFleet();
setInterval(refreshFleet, FLEET_MS);
setInterval(ageTracks, 500);
