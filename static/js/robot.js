// A robot's page: its sub-map with pose, trail, plan, laser and goal; velocity plots; topic
// rates and latency; the camera; and for operators teleoperation, goals and initial pose.

import { api, splitMapId, splitMapRef, urls } from "./api.js";
import { CameraPanel } from "./camera.js";
import { degrees, planarPose, poseStamped, poseWithCovariance, scanPoints } from "./geometry.js";
import { liveness } from "./liveness.js";
import { MapView } from "./mapview.js";
import { followSessions } from "./mapping.js";
import { badge, connectFleet, fixed, navigationState, pageConfig, placePose, showState, stopRobot, whereabouts } from "./page.js";
import { TimePlot } from "./plot.js";
import { RatesPanel } from "./rates.js";
import { Replay } from "./replay.js";
import { Teleop } from "./teleop.js";
import { TopologyView } from "./topology.js";

const TRAIL_POINTS = 600;
const VIDEO_STATS_URL = "/api/video/stats";
const $ = (id) => document.getElementById(id);

const config = pageConfig();
const robot = config.robot;
const ns = `/${robot}`;
const connection = connectFleet();
followSessions(connection);

const state = {
  robotMap: null,
  robotMapVersion: null,
  shownMap: null,
  followRobotMap: true,
  pose: null,
  heard: 0,
  trail: [],
  scan: null,
  plan: { frame: null, points: [] },
  goal: null,
  nav: null,
  whereabouts: null,
};

const grids = new Map();
const view = new MapView($("map-canvas"), {
  onPose: (tool, pose) => sendPose(tool, pose),
  onHover: ({ x, y }) => { $("map-cursor").textContent = `${x.toFixed(2)}, ${y.toFixed(2)} m`; },
});
view.follow = false;
window.cloudnav.robotPage = { view, state };

// ------------------------------------------------------------ the map

async function showMap(mapId) {
  if (!mapId || mapId === state.shownMap) return;
  state.shownMap = mapId;
  $("shown-map").textContent = mapId;
  $("map-wrap").dataset.map = mapId;
  const [building, map] = splitMapId(mapId);
  try {
    if (!grids.has(mapId)) grids.set(mapId, await loadSubmap(building, map));
    if (state.shownMap !== mapId) return;
    const { grid, tags } = grids.get(mapId);
    view.setGrid(grid);
    view.set("tags", tags);
    $("map-wrap").dataset.loaded = mapId;
    if (!view.tool) $("map-hint").hidden = true;
  } catch (error) {
    $("map-hint").hidden = false;
    $("map-hint").textContent = `Cannot load ${mapId}: ${error.message}`;
  }
  drawRobotLayers();
  renderGoalControls();
}

async function loadSubmap(building, map) {
  const [grid, tags] = await Promise.all([api.get(urls.grid(building, map)), api.get(urls.tags(building, map))]);
  return { grid, tags: tags.map((tag) => ({ ...tag, label: `#${tag.marker_id} → ${tag.links_to}` })) };
}

function drawRobotLayers() {
  const here = state.shownMap && state.shownMap === state.robotMap;
  view.set("robot", here ? state.pose : null);
  view.set("trail", here ? state.trail : []);
  view.set("scan", here && state.scan && state.pose ? scanPoints(state.scan, state.pose, 2) : []);
  view.set("plan", state.plan.frame === state.shownMap ? state.plan.points : []);
  view.set("goal", state.goal && state.goal.mapId === state.shownMap ? state.goal.pose : null);
  const wrap = $("map-wrap");
  if (here && state.pose) wrap.dataset.robot = `${state.pose.x.toFixed(3)},${state.pose.y.toFixed(3)}`;
  else delete wrap.dataset.robot;
}

/** The robot is in `mapId`; `version` is the one it holds (from map_id), null when it
 * says none, undefined when this message does not say (a pose). */
function enterMap(mapId, version = undefined) {
  if (!mapId) return;
  const sameMap = mapId === state.robotMap;
  if (sameMap && (version === undefined || version === state.robotMapVersion)) return;
  state.robotMapVersion = version ?? null;
  $("robot-map").textContent = mapId;
  const held = $("robot-map-version");
  held.textContent = state.robotMapVersion === null ? "" : `v${state.robotMapVersion}`;
  held.hidden = state.robotMapVersion === null;
  if (sameMap) {
    // A new version of the map the robot is in: draw it anew.
    grids.delete(mapId);
    if (state.shownMap === mapId) {
      state.shownMap = null;
      showMap(mapId);
    }
    return;
  }
  state.robotMap = mapId;
  state.trail = [];
  if (state.followRobotMap) showMap(mapId);
  topology.show(mapId);
  renderGoalControls();
}

$("map-fit").addEventListener("click", () => view.fit());
$("zoom-in").addEventListener("click", () => view.zoom(1.25));
$("zoom-out").addEventListener("click", () => view.zoom(0.8));
$("map-follow").addEventListener("click", () => {
  view.follow = !view.follow;
  $("map-follow").classList.toggle("active", view.follow);
  if (view.follow && state.pose) view.centerOn(state.pose);
});

// ------------------------------------------------------------ live topics

function heard() {
  state.heard = Date.now();
}

// Each panel's topic handler, fed live by the connection or by a replayed recording.
const handlers = new Map();
function on(topic, type, handle, options) {
  handlers.set(topic, handle);
  connection.subscribe(topic, type, (msg) => { if (!replay.active) handle(msg); }, options);
}

on(`${ns}/pose`, "geometry_msgs/PoseStamped", (msg) => {
  heard();
  enterMap(msg.header.frame_id);
  state.pose = planarPose(msg.pose);
  state.trail.push({ x: state.pose.x, y: state.pose.y });
  if (state.trail.length > TRAIL_POINTS) state.trail.shift();
  $("pose-x").textContent = `${fixed(state.pose.x)} m`;
  $("pose-y").textContent = `${fixed(state.pose.y)} m`;
  $("pose-yaw").textContent = `${fixed(degrees(state.pose.yaw), 0)}°`;
  drawRobotLayers();
});

on(`${ns}/map_id`, "std_msgs/String", (msg) => {
  heard();
  const { mapId, version } = splitMapRef(msg.data);
  enterMap(mapId, version);
});

const linearPlot = new TimePlot($("plot-linear"), [{ label: "linear.x", color: "#2f6fed" }]);
const angularPlot = new TimePlot($("plot-angular"), [{ label: "angular.z (°/s)", color: "#8a4ff0" }]);

on(`${ns}/odom`, "nav_msgs/Odometry", (msg) => {
  heard();
  const { linear, angular } = msg.twist.twist;
  // replaying, the plots run on the recording's clock (its stamps), else on the page's
  const now = replay.active ? msg.header.stamp.sec + msg.header.stamp.nanosec / 1e9 : performance.now() / 1000;
  linearPlot.push(now, [linear.x]);
  angularPlot.push(now, [degrees(angular.z)]);
  $("linear-now").textContent = `${fixed(linear.x)} m/s`;
  $("angular-now").textContent = `${fixed(degrees(angular.z), 0)} °/s`;
  $("odom-speed").textContent = `${fixed(linear.x)} m/s`;
  $("odom-turn").textContent = `${fixed(degrees(angular.z), 0)} °/s`;
});

on(`${ns}/scan`, "sensor_msgs/LaserScan", (msg) => {
  heard();
  state.scan = msg;
  drawRobotLayers();
}, { throttle_rate: 200, queue_length: 1 });

on(`${ns}/plan`, "nav_msgs/Path", (msg) => {
  state.plan = {
    frame: msg.header.frame_id,
    points: msg.poses.map((pose) => ({ x: pose.pose.position.x, y: pose.pose.position.y })),
  };
  drawRobotLayers();
});

on(`${ns}/nav_status`, "actionlib_msgs/GoalStatusArray", (msg) => {
  heard();
  state.nav = msg;
  const [word, kind, text] = navigationState(msg);
  $("robot-nav").replaceWith(Object.assign(badge(`navigation: ${word}`, kind), { id: "robot-nav", title: text }));
  $("nav-text").textContent = text ? `${word}: ${text}` : word;
  renderGoalState(word, kind, text);
});

// Where the robot says it is (its latched `localisation` DiagnosticStatus): a lost robot
// shows no pose, so the page says so, with the way out.
on(`${ns}/localisation`, "diagnostic_msgs/DiagnosticStatus", (msg) => {
  heard();
  state.whereabouts = whereabouts(msg);
  renderWhereabouts();
});

function renderWhereabouts() {
  const found = state.whereabouts;
  if (!found) return;
  const lost = found.state === "lost";
  $("robot-loc").replaceWith(Object.assign(badge(lost ? "lost, looking for a tag" : found.state, found.kind), { id: "robot-loc", title: found.message }));
  $("loc-text").textContent = found.message;
  $("lost-banner").hidden = !lost;
  $("map-wrap").dataset.localisation = found.state;
  if (lost && !state.shownMap) {
    $("map-hint").hidden = false;
    $("map-hint").textContent = $("goal-map")
      ? "No sub-map to show: the robot is lost. Choose the sub-map it is in under Goal."
      : "No sub-map to show: the robot is lost.";
  }
}

setInterval(() => {
  const [word, kind] = liveness(state.heard, "waiting for data");
  const node = $("robot-online");
  node.className = `badge ${kind}`;
  node.textContent = word;
}, 500);

// ------------------------------------------------------------ replay of the recording

// Recorded camera frames (when the building records the camera) play in the camera card
// while replaying, each shown until the next; the live video is hidden meanwhile (CSS).
const replayFrame = $("camera-replay");
handlers.set(`${ns}/camera/image/compressed`, (msg) => {
  const kind = String(msg.format || "").includes("png") ? "png" : "jpeg";
  replayFrame.src = `data:image/${kind};base64,${msg.data}`;
  replayFrame.dataset.stamp = String(msg.header.stamp.sec);
  $("camera-replay-note").hidden = true;
});

function clearPanels() {
  Object.assign(state, { robotMap: null, pose: null, trail: [], scan: null, plan: { frame: null, points: [] }, nav: null });
  drawRobotLayers();
  linearPlot.clear();
  angularPlot.clear();
  replayFrame.removeAttribute("src");
  delete replayFrame.dataset.stamp;
  $("camera-replay-note").hidden = false;
}

const replay = new Replay(robot, handlers, clearPanels, {
  toggle: $("replay-toggle"),
  bar: $("replay-bar"),
  time: $("replay-time"),
  play: $("replay-play"),
  speed: $("replay-speed"),
  clock: $("replay-clock"),
  marks: $("replay-marks"),
  note: $("replay-note"),
});
window.cloudnav.robotPage.replay = replay;
replay.addEventListener("mode", showState);
window.cloudnav.robotPage.plots = { linear: linearPlot, angular: angularPlot };

// ------------------------------------------------------------ rates, camera, topology

new RatesPanel(connection, `${ns}/`, {
  table: $("rates-body"),
  empty: $("rates-empty"),
  latency: $("latency"),
  latencyDetail: $("latency-detail"),
});

const camera = new CameraPanel(connection, `${ns}/camera/image/compressed`, {
  modes: $("camera-modes"),
  frame: $("camera-frame"),
  note: $("camera-note"),
  stalled: $("camera-stalled"),
  fps: $("camera-fps"),
  stats: $("camera-stats"),
  rtc: $("camera-rtc"),
});
camera.show("webrtc");
camera.watchStats(VIDEO_STATS_URL);

/** Before the robot speaks: its last known sub-map from the fleet state, and its building. */
async function showLastKnown() {
  const [building] = config.buildings;
  if (building) topology.show(`${building}/`);
  const entries = await api.get(`${urls.fleet()}?building=${encodeURIComponent(building || "")}`).catch(() => []);
  const entry = entries.find((e) => e.robot === robot);
  if (entry?.map_id && !state.shownMap) showMap(entry.map_id);
  else if (!state.shownMap) {
    $("map-hint").hidden = false;
    $("map-hint").textContent = "Waiting for the robot to report its sub-map…";
  }
}

/** The topology of the building the robot is in, with the robot and its route. */
const topology = {
  view: new TopologyView($("robot-topology")),
  building: null,
  async show(mapId) {
    const [building, map] = splitMapId(mapId);
    if (building && building !== this.building) {
      this.building = building;
      this.view.load(await api.get(urls.topology(building)));
    }
    if (map) this.view.setRobots(new Map([[map, [robot]]]));
  },
  async route(fromMapId, toMapId) {
    const [building, from] = splitMapId(fromMapId);
    const [goalBuilding, to] = splitMapId(toMapId);
    if (!building || building !== goalBuilding) return;
    try {
      const answer = await api.get(urls.route(building, from, to));
      const codes = answer.steps.map((step) => step.map);
      this.view.setRoute(codes);
      $("route-label").textContent = `route: ${codes.join(" → ")}`;
    } catch (error) {
      this.view.setRoute([]);
      $("route-label").textContent = `no route: ${error.message}`;
    }
  },
};

// ------------------------------------------------------------ operators: goals and teleop

/** Whether a sub-map is shown, loaded, for a pose to be in; else say what to do first. */
function mapForPose(tool) {
  const mapId = state.shownMap;
  if (mapId && $("map-wrap").dataset.loaded === mapId) return mapId;
  const what = tool === "goal" ? "A goal" : "An initial pose";
  refuse(`${what} is a pose in a sub-map, and no sub-map is shown: choose one under Goal (Sub-map of the goal) first.`);
  return null;
}

function refuse(text) {
  const hint = $("map-hint");
  hint.hidden = false;
  hint.textContent = text;
  hint.dataset.refused = "true";
  const goal = $("goal-text");
  if (goal) goal.textContent = text;
}

/** Say on the map, where the goal was pressed, that the server moved it (and why). */
function tellMoved(text) {
  const hint = $("map-hint");
  hint.hidden = false;
  hint.textContent = text;
  hint.dataset.moved = "true";
  delete hint.dataset.refused;
  $("goal-text").textContent += ` · ${text}`;
}

async function sendPose(tool, pose) {
  const mapId = mapForPose(tool);
  if (!mapId) {
    selectTool(null, { keepHint: true });
    return;
  }
  // Asked before sending: a place no robot could stand at is refused here, where it was
  // pressed; a spot another robot holds is refused or moved by the building's fleet rule.
  const placed = await placePose(connection, mapId, pose, robot, tool === "goal" ? "goal" : "initial pose");
  if (placed.refusal) {
    refuse(`Not sent: ${placed.refusal}`);
    selectTool(null, { keepHint: true });
    return;
  }
  pose = placed.pose;
  if (tool === "goal") {
    connection.publish(`${ns}/goal`, "geometry_msgs/PoseStamped", poseStamped(mapId, pose));
    state.goal = { mapId, pose };
    $("goal-text").textContent = `${mapId} · x ${fixed(pose.x)} y ${fixed(pose.y)} · ${fixed(degrees(pose.yaw), 0)}°`;
    renderGoalState("sent", "info", "");
    if (placed.note) tellMoved(placed.note);
    if (state.robotMap) topology.route(state.robotMap, mapId);
    // The robot is on its way: show it, and the sub-maps it crosses as it enters them.
    state.followRobotMap = true;
  } else if (tool === "initialpose") {
    connection.publish(`${ns}/initialpose`, "geometry_msgs/PoseWithCovarianceStamped", poseWithCovariance(mapId, pose));
    state.trail = [];
  }
  selectTool(null, { keepHint: Boolean(placed.note) });
  drawRobotLayers();
  if (state.followRobotMap && state.robotMap) showMap(state.robotMap);
}

function selectTool(tool, { keepHint = false } = {}) {
  const tools = $("map-tools");
  if (!tools) return;
  const next = view.tool === tool ? null : tool;
  if (next && !mapForPose(next)) return;
  view.setTool(next);
  for (const button of tools.querySelectorAll("button")) button.classList.toggle("active", button.dataset.tool === next);
  if (keepHint) return;
  const hints = { goal: "Press where the robot should go; drag for its heading.", initialpose: "Press where the robot is; drag for its heading." };
  delete $("map-hint").dataset.refused;
  delete $("map-hint").dataset.moved;
  $("map-hint").hidden = !next;
  $("map-hint").textContent = hints[next] || "";
}

function renderGoalState(word, kind, text) {
  const node = $("goal-state");
  if (!node) return;
  node.className = `badge ${kind}`;
  node.textContent = word;
  node.title = text;
  // Why a goal ended badly is said where the operator looks, not in a tooltip.
  const reason = $("goal-reason");
  const failed = kind === "danger" && Boolean(text);
  reason.hidden = !failed;
  reason.className = `alert ${failed ? "error" : ""}`;
  reason.textContent = failed ? `The robot ${word} the goal: ${text}` : "";
}

function renderGoalControls() {
  const select = $("goal-map");
  if (!select) return;
  if (state.shownMap && select.value !== state.shownMap) select.value = state.shownMap;
  $("back-to-robot").hidden = !state.robotMap || state.shownMap === state.robotMap;
}

async function fillGoalMaps() {
  const select = $("goal-map");
  const lists = await Promise.all(config.buildings.map((b) => api.get(urls.submaps(b))));
  const options = lists.flat().map((submap) => new Option(`${submap.name || submap.code} (${submap.map_id})`, submap.map_id));
  const placeholder = new Option("Choose a sub-map…", "");
  placeholder.disabled = true;
  select.replaceChildren(placeholder, ...options);
  select.value = state.shownMap || "";
  renderGoalControls();
}

async function cancelGoal() {
  try {
    const answer = await connection.call(`${ns}/cancel_goal`, "std_srvs/Trigger", {});
    $("goal-text").textContent = answer.message || (answer.success ? "cancelled" : "nothing to cancel");
  } catch (error) {
    $("goal-text").textContent = `cancel failed: ${error.message}`;
  }
  forgetGoal();
}

/** STOP: the server halts the robot whatever moves it, and the page says what it did. */
async function stop() {
  try {
    $("goal-text").textContent = `Stopped: ${await stopRobot(connection, robot)}`;
  } catch (error) {
    $("goal-text").textContent = `STOP failed: ${error.message}`;
  }
  forgetGoal();
}

function forgetGoal() {
  state.goal = null;
  topology.view.setRoute([]);
  $("route-label").textContent = "";
  drawRobotLayers();
}

function bindOperatorControls() {
  for (const button of $("map-tools").querySelectorAll("button")) {
    button.addEventListener("click", () => selectTool(button.dataset.tool));
  }
  $("goal-map").addEventListener("change", (event) => {
    state.followRobotMap = event.target.value === state.robotMap;
    showMap(event.target.value);
    event.target.blur(); // give the arrow keys back to driving
  });
  $("back-to-robot").addEventListener("click", () => {
    state.followRobotMap = true;
    showMap(state.robotMap);
  });
  $("goal-cancel").addEventListener("click", cancelGoal);
  $("lost-set-pose").addEventListener("click", () => {
    if (view.tool !== "initialpose") selectTool("initialpose");
  });
  const teleop = new Teleop(connection, robot, {
    acquire: $("lock-acquire"),
    release: $("lock-release"),
    keep: $("lock-keep"),
    lockState: $("lock-state"),
    message: $("lock-message"),
    joystick: $("joystick"),
    keys: $("keys"),
    maxLinear: $("max-linear"),
    maxAngular: $("max-angular"),
    maxLinearOut: $("max-linear-out"),
    maxAngularOut: $("max-angular-out"),
  }, config.user);
  const halt = () => {
    teleop.halt();
    stop();
  };
  $("stop-button").addEventListener("click", halt);
  teleop.addEventListener("stop", halt);
  replay.addEventListener("mode", () => teleop.setReplaying(replay.active));
  window.cloudnav.robotPage.teleop = teleop;
  fillGoalMaps();
}

if ($("teleop-card")) bindOperatorControls();
showLastKnown();
