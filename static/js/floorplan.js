// A building's floor plan on Leaflet (plain coordinates, CRS.Simple: one unit a metre,
// latitude = y, longitude = x). Sub-maps share the building's frame, so each one is an
// image overlay at its origin; everything live (robots, trails, plans, goals, routes,
// tags, sub-map outlines) is drawn on one canvas above them, redrawn at most once per
// animation frame, whatever the number of messages. Leaflet gives pan, wheel and pinch
// zoom; the page gives a goal tool: press on the plan and drag for the heading.

import * as L from "../vendor/leaflet.js";
import { yawOfQuaternion } from "./geometry.js";
import { drawArrow, gridPixels } from "./mapview.js";

const COLORS = {
  robot: "#2f6fed",
  selected: "#ff9f1a",
  silent: "#8a93a6",
  trail: "rgba(47, 111, 237, 0.45)",
  plan: "#1f9d55",
  goal: "#d98a00",
  waypoint: "#8a4ff0",
  route: "rgba(217, 138, 0, 0.7)",
  tag: "#b3128a",
  outline: "rgba(28, 35, 51, 0.35)",
  hover: "#2f6fed",
  waiting: "#d64545",
};
const HIT_RADIUS_PX = 16;
const DRAG_THRESHOLD_PX = 4;
const DRAW_TIMES = 600;
const CLICK_AFTER_POSE_MS = 400;
// Layers a person can switch off, with their label; sub-map images are one of them.
export const LAYERS = {
  submaps: "Sub-maps",
  outlines: "Outlines",
  tags: "Tags",
  trails: "Trails",
  plans: "Plans",
  routes: "Goals and routes",
  labels: "Names",
};

/** A sub-map's origin in the building frame: {x, y, yaw} of its bottom-left cell's corner. */
function originOf(grid) {
  const { position, orientation } = grid.info.origin;
  return { x: position.x, y: position.y, yaw: yawOfQuaternion(orientation) };
}

/** A sub-map's corners in the building frame, turned by its origin's yaw (map_server):
 * bottom-left (the origin), bottom-right, top-right, top-left. */
export function corners(grid) {
  const { width, height, resolution } = grid.info;
  const { x, y, yaw } = originOf(grid);
  const [cos, sin] = [Math.cos(yaw), Math.sin(yaw)];
  const [w, h] = [width * resolution, height * resolution];
  return [[0, 0], [w, 0], [w, h], [0, h]].map(([u, v]) => ({ x: x + cos * u - sin * v, y: y + sin * u + cos * v }));
}

/** The box around a sub-map in the building frame: [x0, y0, x1, y1]. */
export function footprint(grid) {
  const points = corners(grid);
  const xs = points.map((p) => p.x);
  const ys = points.map((p) => p.y);
  return [Math.min(...xs), Math.min(...ys), Math.max(...xs), Math.max(...ys)];
}

/** The occupancy value of `grid` at building point (x, y), or undefined outside it. */
export function cellAt(grid, x, y) {
  const { width, height, resolution } = grid.info;
  const origin = originOf(grid);
  const [dx, dy, cos, sin] = [x - origin.x, y - origin.y, Math.cos(origin.yaw), Math.sin(origin.yaw)];
  const col = Math.floor((cos * dx + sin * dy) / resolution);
  const row = Math.floor((-sin * dx + cos * dy) / resolution);
  if (col < 0 || row < 0 || col >= width || row >= height) return undefined;
  return grid.data[row * width + col];
}

/**
 * A sub-map's image in the building frame: Leaflet places it unturned on its origin, and
 * CSS turns it about its bottom-left corner (the origin) by the origin's yaw.
 */
const SubmapImage = L.ImageOverlay.extend({
  initialize(url, grid, options) {
    const { width, height, resolution } = grid.info;
    const { x, y, yaw } = originOf(grid);
    L.ImageOverlay.prototype.initialize.call(this, url, [[y, x], [y + height * resolution, x + width * resolution]], options);
    this.yaw = yaw;
  },

  _reset() {
    L.ImageOverlay.prototype._reset.call(this);
    if (!this.yaw) return;
    this._image.style.transformOrigin = "0 100%";
    this._image.style.transform += ` rotate(${-this.yaw}rad)`;
  },
});

/**
 * The sub-map a point belongs to, of `submaps` (code -> grid): the `preferred` one if the
 * point is free there, else the first where it is free, else the first that covers it
 * (sub-maps overlap where tags stand); null outside them all.
 */
export function submapAt(submaps, x, y, preferred = null) {
  const order = [...submaps.keys()].sort((a, b) => (a === preferred ? -1 : b === preferred ? 1 : 0));
  const free = order.find((code) => cellAt(submaps.get(code), x, y) === 0);
  return free ?? order.find((code) => cellAt(submaps.get(code), x, y) !== undefined) ?? null;
}

/** A canvas above the map's panes, sized to its container and redrawn by `draw(ctx, project)`. */
const LiveCanvas = L.Layer.extend({
  initialize(draw) {
    this._draw = draw;
    this._frame = null;
    // The last drawings' durations (ms), for the page to report its own cost.
    this.drawTimes = new Float64Array(DRAW_TIMES);
    this.drawn = 0;
  },

  onAdd(map) {
    const pane = map.getPane("live") || map.createPane("live");
    pane.style.zIndex = 450;
    pane.style.pointerEvents = "none";
    this._canvas = L.DomUtil.create("canvas", "live-canvas", pane);
    map.on("move zoom resize viewreset", this._reset, this);
    this._reset();
  },

  onRemove(map) {
    map.off("move zoom resize viewreset", this._reset, this);
    this._canvas.remove();
  },

  /** Draw in the next animation frame (many calls, one drawing). */
  redraw() {
    if (this._frame || !this._map) return;
    this._frame = requestAnimationFrame(() => {
      this._frame = null;
      this._paint();
    });
  },

  // Moved or zoomed: the canvas follows the container now, so no frame shows it shifted.
  _reset() {
    const map = this._map;
    const size = map.getSize();
    const ratio = window.devicePixelRatio || 1;
    const canvas = this._canvas;
    L.DomUtil.setPosition(canvas, map.containerPointToLayerPoint([0, 0]));
    if (canvas.width !== Math.round(size.x * ratio) || canvas.height !== Math.round(size.y * ratio)) {
      canvas.width = Math.round(size.x * ratio);
      canvas.height = Math.round(size.y * ratio);
      canvas.style.width = `${size.x}px`;
      canvas.style.height = `${size.y}px`;
    }
    this._paint();
  },

  _paint() {
    const map = this._map;
    if (!map) return;
    const ratio = window.devicePixelRatio || 1;
    const ctx = this._canvas.getContext("2d");
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, this._canvas.width, this._canvas.height);
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    const started = performance.now();
    this._draw(ctx, projector(map));
    this.drawTimes[this.drawn % DRAW_TIMES] = performance.now() - started;
    this.drawn += 1;
  },
});

/** World (x, y) in metres to container pixels, for this frame: CRS.Simple is linear. */
function projector(map) {
  const zero = map.latLngToContainerPoint([0, 0]);
  const scale = map.getZoomScale(map.getZoom(), 0);
  const project = (x, y) => [zero.x + x * scale, zero.y - y * scale];
  project.scale = scale;
  return project;
}

export class FloorPlan extends EventTarget {
  constructor(element) {
    super();
    this.map = L.map(element, {
      crs: L.CRS.Simple,
      minZoom: -3,
      maxZoom: 7,
      zoomSnap: 0.25,
      zoomDelta: 0.5,
      wheelPxPerZoomLevel: 90,
      // The live canvas follows every move and zoom step; animated zooms would slide the
      // images under it for a quarter of a second.
      zoomAnimation: false,
      attributionControl: false,
      boxZoom: false,
      doubleClickZoom: false,
    });
    this.map.setView([0, 0], 2);
    this.element = element;
    this.grids = new Map(); // code -> OccupancyGrid
    this.tags = [];
    // Mission waypoints to show: [{x, y, yaw}] of the selected robot's mission or a draft.
    this.waypoints = [];
    this.robots = new Map(); // name -> RobotTrack (see buildingmap.js)
    this.selected = null;
    this.hover = null;
    this.tool = null;
    this.drag = null;
    this.posedAt = -Infinity;
    this.visible = Object.fromEntries(Object.keys(LAYERS).map((key) => [key, true]));
    this.images = L.layerGroup().addTo(this.map);
    this.live = new LiveCanvas((ctx, project) => this.#draw(ctx, project)).addTo(this.map);
    this.#bindPointer();
    // The layout (a phone turned, a panel opened) resizes the plan, not only the window.
    new ResizeObserver(() => this.map.invalidateSize({ pan: false })).observe(element);
  }

  // ------------------------------------------------------------ content

  /** Add sub-map `code`'s grid as an image in the building frame. */
  addSubmap(code, grid) {
    this.grids.set(code, grid);
    const { width, height } = grid.info;
    const canvas = document.createElement("canvas");
    canvas.width = width;
    canvas.height = height;
    // Unknown cells are transparent, so where sub-maps overlap each shows what it knows.
    canvas.getContext("2d").putImageData(new ImageData(gridPixels(grid, { unknownAlpha: 0 }), width, height), 0, 0);
    new SubmapImage(canvas.toDataURL(), grid, { className: "submap-image", alt: code }).addTo(this.images);
    this.live.redraw();
  }

  setTags(tags) {
    this.tags = tags;
    this.live.redraw();
  }

  /** Zoom and pan so every sub-map shows. */
  fit() {
    const boxes = [...this.grids.values()].map(footprint);
    if (!boxes.length) return;
    const x0 = Math.min(...boxes.map((b) => b[0]));
    const y0 = Math.min(...boxes.map((b) => b[1]));
    const x1 = Math.max(...boxes.map((b) => b[2]));
    const y1 = Math.max(...boxes.map((b) => b[3]));
    this.map.fitBounds([[y0, x0], [y1, x1]], { padding: [12, 12], animate: false });
  }

  setLayer(key, on) {
    this.visible[key] = on;
    if (key === "submaps") {
      if (on) this.images.addTo(this.map);
      else this.images.remove();
    }
    this.live.redraw();
  }

  /** Something live changed: draw it in the next frame. */
  changed() {
    this.live.redraw();
  }

  centerOn(x, y) {
    this.map.panTo([y, x], { animate: false });
  }

  select(name) {
    this.selected = name;
    this.live.redraw();
    this.dispatchEvent(new CustomEvent("select", { detail: { name } }));
  }

  setTool(tool) {
    this.tool = tool;
    this.drag = null;
    if (tool) this.map.dragging.disable();
    else this.map.dragging.enable();
    this.element.classList.toggle("tool-active", Boolean(tool));
    this.live.redraw();
  }

  /** Where the building point (x, y) is on the page, for tests and tools. */
  toPage(x, y) {
    const point = this.map.latLngToContainerPoint([y, x]);
    const rect = this.element.getBoundingClientRect();
    return [rect.left + point.x, rect.top + point.y];
  }

  toWorld(event) {
    const latlng = this.map.mouseEventToLatLng(event);
    return { x: latlng.lng, y: latlng.lat };
  }

  // ------------------------------------------------------------ pointer

  #bindPointer() {
    const box = this.element;
    box.addEventListener("pointerdown", (event) => this.#down(event), true);
    box.addEventListener("pointermove", (event) => this.#move(event), true);
    box.addEventListener("pointerup", (event) => this.#up(event), true);
    box.addEventListener("pointercancel", () => { this.drag = null; this.live.redraw(); }, true);
    this.map.on("click", (event) => this.#click(event));
  }

  #down(event) {
    if (!this.tool || event.button !== 0 || event.target.closest(".leaflet-control")) return;
    event.stopPropagation();
    this.element.setPointerCapture(event.pointerId);
    const start = this.toWorld(event);
    this.drag = { start, end: start, sx: event.clientX, sy: event.clientY };
  }

  #move(event) {
    const at = this.toWorld(event);
    const code = submapAt(this.grids, at.x, at.y, this.#preferredMap());
    if (code !== this.hover) {
      this.hover = code;
      this.live.redraw();
    }
    this.dispatchEvent(new CustomEvent("hover", { detail: { ...at, map: code } }));
    if (!this.drag) return;
    event.stopPropagation();
    this.drag.end = at;
    this.live.redraw();
  }

  #up(event) {
    const drag = this.drag;
    if (!drag) return;
    event.stopPropagation();
    this.drag = null;
    this.posedAt = performance.now(); // the click this release makes is not a selection
    const pose = this.#dragPose(drag, event);
    const map = submapAt(this.grids, pose.x, pose.y, this.#preferredMap());
    this.dispatchEvent(new CustomEvent("pose", { detail: { tool: this.tool, pose, map } }));
    this.live.redraw();
  }

  /** The pose a drag makes: its start, heading towards the pointer (0 when not dragged). */
  #dragPose(drag, event = null) {
    const end = event ? this.toWorld(event) : drag.end;
    const moved = event ? Math.hypot(event.clientX - drag.sx, event.clientY - drag.sy) > DRAG_THRESHOLD_PX : true;
    const yaw = moved ? Math.atan2(end.y - drag.start.y, end.x - drag.start.x) : 0;
    return { x: drag.start.x, y: drag.start.y, yaw };
  }

  #preferredMap() {
    const track = this.selected && this.robots.get(this.selected);
    return track ? track.map : null;
  }

  #click(event) {
    if (this.tool || performance.now() - this.posedAt < CLICK_AFTER_POSE_MS) return;
    const point = event.containerPoint;
    const project = projector(this.map);
    let best = null;
    let bestDistance = HIT_RADIUS_PX;
    for (const track of this.robots.values()) {
      if (!track.pose) continue;
      const [sx, sy] = project(track.pose.x, track.pose.y);
      const distance = Math.hypot(sx - point.x, sy - point.y);
      if (distance < bestDistance) {
        best = track.name;
        bestDistance = distance;
      }
    }
    this.select(best);
  }

  // ------------------------------------------------------------ drawing

  #draw(ctx, project) {
    if (this.visible.outlines) this.#drawOutlines(ctx, project);
    if (this.visible.tags) this.tags.forEach((tag) => this.#drawTag(ctx, project, tag));
    const tracks = [...this.robots.values()];
    if (this.visible.trails) tracks.forEach((t) => polyline(ctx, project, t.trail, COLORS.trail, 2));
    if (this.visible.plans) tracks.forEach((t) => polyline(ctx, project, t.plan, COLORS.plan, 2, [6, 4]));
    if (this.visible.routes) tracks.forEach((t) => this.#drawGoal(ctx, project, t));
    if (this.visible.routes) this.#drawWaypoints(ctx, project);
    tracks.forEach((t) => this.#drawGiveWay(ctx, project, t));
    tracks.forEach((t) => this.#drawRobot(ctx, project, t));
    if (this.drag) {
      const color = this.tool === "waypoint" ? COLORS.waypoint : COLORS.goal;
      arrow(ctx, project, this.#dragPose(this.drag), color, project.scale);
    }
  }

  #drawOutlines(ctx, project) {
    ctx.save();
    ctx.font = "600 12px system-ui, sans-serif";
    for (const [code, grid] of this.grids) {
      const outline = corners(grid).map((p) => project(p.x, p.y));
      const hovered = code === this.hover && this.tool;
      ctx.strokeStyle = hovered ? COLORS.hover : COLORS.outline;
      ctx.lineWidth = hovered ? 2.5 : 1;
      ctx.setLineDash(hovered ? [] : [4, 4]);
      ctx.beginPath();
      outline.forEach(([sx, sy], index) => (index ? ctx.lineTo(sx, sy) : ctx.moveTo(sx, sy)));
      ctx.closePath();
      ctx.stroke();
      // The name stands inside the corner nearest the top left of the screen.
      const [ax, ay] = outline.reduce((best, point) => (point[0] + point[1] < best[0] + best[1] ? point : best));
      if (this.visible.labels) label(ctx, code, ax + 4, ay + 14, hovered ? COLORS.hover : "#4a5468");
    }
    ctx.restore();
  }

  #drawTag(ctx, project, tag) {
    const [sx, sy] = project(tag.x, tag.y);
    ctx.save();
    ctx.translate(sx, sy);
    ctx.rotate(-tag.yaw);
    ctx.fillStyle = COLORS.tag;
    ctx.fillRect(-2, -5, 4, 10);
    ctx.restore();
    if (this.visible.labels && project.scale > 12) label(ctx, `#${tag.marker_id}`, sx + 6, sy + 12, COLORS.tag);
  }

  #drawGoal(ctx, project, track) {
    if (!track.goal) return;
    if (track.pose && track.route.length) {
      polyline(ctx, project, [track.pose, ...track.route, track.goal.pose], COLORS.route, 2, [2, 5]);
    }
    arrow(ctx, project, track.goal.pose, COLORS.goal, project.scale);
  }

  #drawWaypoints(ctx, project) {
    polyline(ctx, project, this.waypoints, COLORS.waypoint, 1.5, [4, 4]);
    this.waypoints.forEach((point, index) => {
      arrow(ctx, project, point, COLORS.waypoint, Math.min(project.scale, 30));
      const [sx, sy] = project(point.x, point.y);
      label(ctx, String(index + 1), sx - 12, sy - 6, COLORS.waypoint);
    });
  }

  /** Where a robot giving way waits (a ring), joined to the narrow place it waits for. */
  #drawGiveWay(ctx, project, track) {
    const way = track.giveWay;
    if (!way) return;
    polyline(ctx, project, [way.spot, way.place], COLORS.waiting, 1.5, [3, 3]);
    const [sx, sy] = project(way.spot.x, way.spot.y);
    const [px, py] = project(way.place.x, way.place.y);
    ctx.save();
    ctx.strokeStyle = COLORS.waiting;
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.arc(sx, sy, Math.max(6, 0.25 * project.scale), 0, Math.PI * 2);
    ctx.stroke();
    ctx.fillStyle = COLORS.waiting;
    ctx.fillRect(px - 3, py - 3, 6, 6);
    ctx.restore();
    label(ctx, `${track.name} waits for ${way.waitingFor}`, sx + 8, sy + 14, COLORS.waiting);
  }

  #drawRobot(ctx, project, track) {
    if (!track.pose) return;
    const [sx, sy] = project(track.pose.x, track.pose.y);
    const radius = Math.max(6, 0.2 * project.scale);
    const selected = track.name === this.selected;
    ctx.save();
    ctx.translate(sx, sy);
    ctx.rotate(-track.pose.yaw);
    ctx.fillStyle = track.live ? (selected ? COLORS.selected : COLORS.robot) : COLORS.silent;
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.arc(0, 0, radius, 0, Math.PI * 2);
    ctx.fill();
    ctx.stroke();
    ctx.fillStyle = "#fff";
    ctx.beginPath();
    ctx.moveTo(radius * 0.85, 0);
    ctx.lineTo(-radius * 0.35, radius * 0.5);
    ctx.lineTo(-radius * 0.35, -radius * 0.5);
    ctx.closePath();
    ctx.fill();
    ctx.restore();
    if (this.visible.labels || selected) {
      const text = track.live ? track.name : `${track.name} (silent)`;
      label(ctx, text, sx + radius + 4, sy - radius, track.live ? "#1c2333" : COLORS.silent);
    }
  }
}

function polyline(ctx, project, points, color, width, dash = []) {
  if (!points || points.length < 2) return;
  ctx.save();
  ctx.strokeStyle = color;
  ctx.lineWidth = width;
  ctx.lineJoin = "round";
  ctx.setLineDash(dash);
  ctx.beginPath();
  for (let i = 0; i < points.length; i += 1) {
    const [sx, sy] = project(points[i].x, points[i].y);
    if (i === 0) ctx.moveTo(sx, sy);
    else ctx.lineTo(sx, sy);
  }
  ctx.stroke();
  ctx.restore();
}

function arrow(ctx, project, pose, color, scale) {
  const [sx, sy] = project(pose.x, pose.y);
  drawArrow(ctx, sx, sy, pose.yaw, color, { length: Math.max(18, 0.5 * scale), dot: 4, head: 6 });
}

function label(ctx, text, sx, sy, color) {
  ctx.save();
  ctx.font = "600 11px system-ui, sans-serif";
  ctx.lineWidth = 3;
  ctx.strokeStyle = "rgba(255,255,255,0.9)";
  ctx.strokeText(text, sx, sy);
  ctx.fillStyle = color;
  ctx.fillText(text, sx, sy);
  ctx.restore();
}
