// A sub-map on a canvas: the occupancy grid (nav_msgs/OccupancyGrid, row 0 at the bottom),
// tags, the robot with its trail, plan, laser points and goal, with pan and zoom. A tool
// (goal, initial pose, tag) turns press-and-drag into a pose: the press is the position,
// the drag the heading.

import { yawOfQuaternion } from "./geometry.js";

const COLORS = {
  unknown: [201, 206, 217],
  occupied: [28, 35, 51],
  free: [255, 255, 255],
  trail: "rgba(47, 111, 237, 0.55)",
  plan: "#1f9d55",
  scan: "#e0412f",
  robot: "#2f6fed",
  goal: "#d98a00",
  initialpose: "#8a4ff0",
  tag: "#b3128a",
  keyframe: "rgba(0, 150, 170, 0.7)",
  selected: "#ff9f1a",
  added: [224, 65, 47, 230],
  removed: [31, 157, 85, 230],
  cleared: [47, 111, 237, 200],
};
const DRAG_THRESHOLD_PX = 4;
const ZOOM_STEP = 1.15;

/**
 * RGBA pixels of a grid message, top row first, for an offscreen canvas; unknown cells get
 * alpha `unknownAlpha` (a floor plan of overlapping sub-maps makes them transparent).
 */
export function gridPixels(grid, { unknownAlpha = 255 } = {}) {
  const { width, height } = grid.info;
  const pixels = new Uint8ClampedArray(width * height * 4);
  for (let row = 0; row < height; row += 1) {
    const source = (height - 1 - row) * width;
    for (let col = 0; col < width; col += 1) {
      const value = grid.data[source + col];
      const [r, g, b] = cellColor(value);
      const at = (row * width + col) * 4;
      pixels[at] = r;
      pixels[at + 1] = g;
      pixels[at + 2] = b;
      pixels[at + 3] = value < 0 || value > 100 ? unknownAlpha : 255;
    }
  }
  return pixels;
}

function cellColor(value) {
  if (value < 0 || value > 100) return COLORS.unknown;
  if (value === 0) return COLORS.free;
  if (value === 100) return COLORS.occupied;
  const grey = Math.round(255 - (value / 100) * 227);
  return [grey, grey, grey];
}

/** A pose as a dot with an arrow along its yaw, at screen point (sx, sy): `length` of the
 * shaft in pixels, `dot` the dot's radius, `head` the arrowhead's half width. */
export function drawArrow(ctx, sx, sy, yaw, color, { length, dot = 5, head = 7 }) {
  ctx.save();
  ctx.translate(sx, sy);
  ctx.rotate(-yaw);
  ctx.strokeStyle = color;
  ctx.fillStyle = color;
  ctx.lineWidth = 3;
  ctx.beginPath();
  ctx.arc(0, 0, dot, 0, Math.PI * 2);
  ctx.fill();
  ctx.beginPath();
  ctx.moveTo(0, 0);
  ctx.lineTo(length, 0);
  ctx.stroke();
  ctx.beginPath();
  ctx.moveTo(length + 4, 0);
  ctx.lineTo(length - head - 1, head);
  ctx.lineTo(length - head - 1, -head);
  ctx.closePath();
  ctx.fill();
  ctx.restore();
}

export class MapView {
  constructor(canvas, { onPose = null, onClick = null, onHover = null } = {}) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.onPose = onPose;
    this.onClick = onClick;
    this.onHover = onHover;
    this.view = { cx: 0, cy: 0, scale: 40 };
    this.layers = { tags: [], trail: [], plan: [], scan: [], keyframes: [], robot: null, goal: null };
    this.grid = null;
    this.image = null;
    this.overlay = null;
    this.tool = null;
    this.painter = null;
    this.drag = null;
    this.pointers = new Map(); // pointerId -> position, for pinches
    this.pinch = null;
    this.follow = false;
    this.pending = null;
    new ResizeObserver(() => this.#resize()).observe(canvas);
    this.#bindPointer();
    this.#resize();
  }

  // ------------------------------------------------------------ content

  setGrid(grid) {
    this.grid = grid;
    this.overlay = null;
    const { width, height } = grid.info;
    const image = document.createElement("canvas");
    image.width = width;
    image.height = height;
    image.getContext("2d").putImageData(new ImageData(gridPixels(grid), width, height), 0, 0);
    this.image = image;
    this.fit();
  }

  /** Mark cells of the grid shown: { added: [[row, col], ...], removed: [...], cleared:
   * [...] (made unknown) } (rows counted from the bottom, as in the grid), drawn over
   * it; null clears them. */
  setCells(cells) {
    this.overlay = null;
    if (cells && this.grid) {
      const { width, height } = this.grid.info;
      const pixels = new Uint8ClampedArray(width * height * 4);
      for (const kind of ["added", "removed", "cleared"]) {
        for (const [row, col] of cells[kind] || []) {
          if (row < 0 || row >= height || col < 0 || col >= width) continue;
          pixels.set(COLORS[kind], ((height - 1 - row) * width + col) * 4);
        }
      }
      const image = document.createElement("canvas");
      image.width = width;
      image.height = height;
      image.getContext("2d").putImageData(new ImageData(pixels, width, height), 0, 0);
      this.overlay = image;
    }
    this.redraw();
  }

  /** Set one layer: tags, trail, plan, scan (arrays) or robot, goal (a pose or null). */
  set(layer, value) {
    this.layers[layer] = value;
    if (layer === "robot" && value && this.follow) this.centerOn(value);
    this.redraw();
  }

  setTool(tool) {
    this.tool = tool;
    this.canvas.parentElement?.classList.toggle("tool-active", Boolean(tool));
    this.drag = null;
    this.redraw();
  }

  /** While `painter` is set, one pointer (mouse or finger) paints instead of panning:
   * `painter.paint({x, y})` at the press and at each move, `painter.end()` when it lifts;
   * two fingers still pinch. null stops painting. */
  setPainter(painter) {
    this.painter?.end();
    this.painter = painter;
    this.canvas.parentElement?.classList.toggle("tool-active", Boolean(painter));
    this.drag = null;
  }

  /** The grid cell [row, col] (row 0 at the bottom) under a world point, or null. */
  cellAt({ x, y }) {
    if (!this.grid) return null;
    const { width, height, resolution } = this.grid.info;
    const [ox, oy, yaw] = this.#origin();
    const dx = x - ox;
    const dy = y - oy;
    const col = Math.floor((Math.cos(yaw) * dx + Math.sin(yaw) * dy) / resolution);
    const row = Math.floor((-Math.sin(yaw) * dx + Math.cos(yaw) * dy) / resolution);
    return row >= 0 && row < height && col >= 0 && col < width ? [row, col] : null;
  }

  centerOn({ x, y }) {
    this.view.cx = x;
    this.view.cy = y;
    this.redraw();
  }

  /** Zoom and pan so the whole grid shows. */
  fit() {
    if (!this.grid) return;
    const { width, height, resolution } = this.grid.info;
    const [ox, oy] = this.#origin();
    const w = width * resolution;
    const h = height * resolution;
    const box = this.#size();
    this.view.scale = Math.max(0.5, Math.min(box.width / w, box.height / h) * 0.94);
    this.view.cx = ox + w / 2;
    this.view.cy = oy + h / 2;
    this.redraw();
  }

  zoom(factor, at = null) {
    const box = this.#size();
    const anchor = at || { sx: box.width / 2, sy: box.height / 2 };
    const before = this.toWorld(anchor.sx, anchor.sy);
    this.view.scale = Math.min(2000, Math.max(0.5, this.view.scale * factor));
    const after = this.toWorld(anchor.sx, anchor.sy);
    this.view.cx += before.x - after.x;
    this.view.cy += before.y - after.y;
    this.redraw();
  }

  // ------------------------------------------------------------ coordinates

  toScreen(x, y) {
    const box = this.#size();
    return {
      sx: box.width / 2 + (x - this.view.cx) * this.view.scale,
      sy: box.height / 2 - (y - this.view.cy) * this.view.scale,
    };
  }

  toWorld(sx, sy) {
    const box = this.#size();
    return {
      x: this.view.cx + (sx - box.width / 2) / this.view.scale,
      y: this.view.cy - (sy - box.height / 2) / this.view.scale,
    };
  }

  #origin() {
    const origin = this.grid.info.origin;
    return [origin.position.x, origin.position.y, yawOfQuaternion(origin.orientation)];
  }

  #size() {
    return { width: this.canvas.clientWidth || 1, height: this.canvas.clientHeight || 1 };
  }

  #resize() {
    const ratio = window.devicePixelRatio || 1;
    const box = this.#size();
    this.canvas.width = Math.round(box.width * ratio);
    this.canvas.height = Math.round(box.height * ratio);
    this.redraw();
  }

  // ------------------------------------------------------------ pointer

  #bindPointer() {
    const canvas = this.canvas;
    canvas.addEventListener("pointerdown", (event) => this.#down(event));
    canvas.addEventListener("pointermove", (event) => this.#move(event));
    canvas.addEventListener("pointerup", (event) => this.#up(event));
    canvas.addEventListener("pointercancel", (event) => {
      this.pointers.delete(event.pointerId);
      if (this.drag) this.painter?.end();
      this.drag = null;
      this.pinch = null;
      this.redraw();
    });
    canvas.addEventListener("wheel", (event) => {
      event.preventDefault();
      const at = this.#local(event);
      this.zoom(event.deltaY < 0 ? ZOOM_STEP : 1 / ZOOM_STEP, at);
    }, { passive: false });
  }

  #local(event) {
    const rect = this.canvas.getBoundingClientRect();
    return { sx: event.clientX - rect.left, sy: event.clientY - rect.top };
  }

  /** Two fingers: their midpoint and spread, for a pinch. */
  #pinchState() {
    const [a, b] = [...this.pointers.values()];
    return { mid: { sx: (a.sx + b.sx) / 2, sy: (a.sy + b.sy) / 2 }, spread: Math.max(1, Math.hypot(a.sx - b.sx, a.sy - b.sy)) };
  }

  /** A pinch moved: zoom about the fingers' midpoint by how much they spread, pan with it. */
  #pinchTo(now) {
    const before = this.pinch;
    this.zoom(now.spread / before.spread, now.mid);
    this.view.cx -= (now.mid.sx - before.mid.sx) / this.view.scale;
    this.view.cy += (now.mid.sy - before.mid.sy) / this.view.scale;
    this.follow = false;
    this.pinch = now;
  }

  #down(event) {
    if (event.button !== 0) return;
    this.canvas.setPointerCapture(event.pointerId);
    const at = this.#local(event);
    this.pointers.set(event.pointerId, at);
    if (this.pointers.size >= 2) {
      if (this.drag) this.painter?.end();
      this.drag = null; // a second finger: a pinch, never a pose or a stroke
      this.pinch = this.#pinchState();
      return;
    }
    this.drag = { start: at, last: at, moved: false, world: this.toWorld(at.sx, at.sy) };
    this.painter?.paint(this.drag.world);
  }

  #move(event) {
    const at = this.#local(event);
    if (this.pointers.has(event.pointerId)) this.pointers.set(event.pointerId, at);
    if (this.pinch) {
      this.#pinchTo(this.#pinchState());
      return;
    }
    this.onHover?.(this.toWorld(at.sx, at.sy));
    if (!this.drag) return;
    const { start, last } = this.drag;
    if (Math.hypot(at.sx - start.sx, at.sy - start.sy) > DRAG_THRESHOLD_PX) this.drag.moved = true;
    if (this.painter) {
      this.painter.paint(this.toWorld(at.sx, at.sy));
    } else if (!this.tool) {
      this.view.cx -= (at.sx - last.sx) / this.view.scale;
      this.view.cy += (at.sy - last.sy) / this.view.scale;
      this.follow = false;
    }
    this.drag.last = at;
    this.redraw();
  }

  #up(event) {
    this.pointers.delete(event.pointerId);
    if (this.pinch) {
      if (this.pointers.size < 2) this.pinch = null;
      this.drag = null;
      return;
    }
    const drag = this.drag;
    this.drag = null;
    if (!drag) return;
    if (this.painter) {
      this.painter.end();
      return;
    }
    const at = this.#local(event);
    if (this.tool) this.onPose?.(this.tool, this.#dragPose(drag.world, at));
    else if (!drag.moved) this.onClick?.(drag.world, at);
    this.redraw();
  }

  /** The pose a drag makes: its start, heading towards the pointer (0 when not dragged). */
  #dragPose(start, at) {
    const end = this.toWorld(at.sx, at.sy);
    const dx = end.x - start.x;
    const dy = end.y - start.y;
    const long = Math.hypot(dx, dy) * this.view.scale > DRAG_THRESHOLD_PX;
    return { x: start.x, y: start.y, yaw: long ? Math.atan2(dy, dx) : 0 };
  }

  // ------------------------------------------------------------ drawing

  redraw() {
    if (this.pending) return;
    this.pending = requestAnimationFrame(() => {
      this.pending = null;
      this.#draw();
    });
  }

  #draw() {
    const ctx = this.ctx;
    const ratio = window.devicePixelRatio || 1;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    this.#drawGrid(ratio);
    this.#drawPolyline(this.layers.trail, COLORS.trail, 2.5);
    this.#drawPolyline(this.layers.plan, COLORS.plan, 2.5, [7, 5]);
    this.#drawScan();
    this.#drawKeyframes();
    this.layers.tags.forEach((tag) => this.#drawTag(tag));
    if (this.layers.goal) this.#drawArrow(this.layers.goal, COLORS.goal, "goal");
    if (this.layers.robot) this.#drawRobot(this.layers.robot);
    this.#drawDragPreview();
    this.#drawScaleBar();
  }

  #drawGrid(ratio) {
    if (!this.image) return;
    const { resolution: res, height } = this.grid.info;
    const [ox, oy, yaw] = this.#origin();
    const s = this.view.scale;
    const cos = Math.cos(yaw);
    const sin = Math.sin(yaw);
    const top = this.toScreen(ox - sin * height * res, oy + cos * height * res);
    const ctx = this.ctx;
    ctx.save();
    ctx.setTransform(
      ratio * s * cos * res, -ratio * s * sin * res,
      ratio * s * sin * res, ratio * s * cos * res,
      ratio * top.sx, ratio * top.sy,
    );
    ctx.imageSmoothingEnabled = s * res < 2;
    ctx.drawImage(this.image, 0, 0);
    if (this.overlay) {
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(this.overlay, 0, 0);
    }
    ctx.restore();
  }

  #drawPolyline(points, color, width, dash = []) {
    if (!points || points.length < 2) return;
    const ctx = this.ctx;
    ctx.save();
    ctx.strokeStyle = color;
    ctx.lineWidth = width;
    ctx.lineJoin = "round";
    ctx.setLineDash(dash);
    ctx.beginPath();
    points.forEach((point, index) => {
      const { sx, sy } = this.toScreen(point.x, point.y);
      if (index === 0) ctx.moveTo(sx, sy);
      else ctx.lineTo(sx, sy);
    });
    ctx.stroke();
    ctx.restore();
  }

  #drawScan() {
    const ctx = this.ctx;
    ctx.fillStyle = COLORS.scan;
    for (const point of this.layers.scan || []) {
      const { sx, sy } = this.toScreen(point.x, point.y);
      ctx.fillRect(sx - 1.5, sy - 1.5, 3, 3);
    }
  }

  /** Keyframe poses (the visual map's coverage): a dot and a short heading tick each. */
  #drawKeyframes() {
    const ctx = this.ctx;
    const reach = Math.max(6, 0.25 * this.view.scale);
    ctx.strokeStyle = COLORS.keyframe;
    ctx.fillStyle = COLORS.keyframe;
    ctx.lineWidth = 1.5;
    for (const pose of this.layers.keyframes || []) {
      const { sx, sy } = this.toScreen(pose.x, pose.y);
      ctx.beginPath();
      ctx.arc(sx, sy, 2, 0, Math.PI * 2);
      ctx.fill();
      ctx.beginPath();
      ctx.moveTo(sx, sy);
      ctx.lineTo(sx + reach * Math.cos(pose.yaw), sy - reach * Math.sin(pose.yaw));
      ctx.stroke();
    }
  }

  #drawRobot(pose) {
    const ctx = this.ctx;
    const { sx, sy } = this.toScreen(pose.x, pose.y);
    const radius = Math.max(7, 0.2 * this.view.scale);
    ctx.save();
    ctx.translate(sx, sy);
    ctx.rotate(-pose.yaw);
    ctx.fillStyle = COLORS.robot;
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
  }

  #drawArrow(pose, color, label = "") {
    const ctx = this.ctx;
    const { sx, sy } = this.toScreen(pose.x, pose.y);
    drawArrow(ctx, sx, sy, pose.yaw, color, { length: Math.max(26, 0.6 * this.view.scale) });
    if (label) this.#label(label, sx + 8, sy - 10, color);
  }

  #drawTag(tag) {
    const ctx = this.ctx;
    const { sx, sy } = this.toScreen(tag.x, tag.y);
    const color = tag.selected ? COLORS.selected : COLORS.tag;
    const half = 7;
    ctx.save();
    ctx.translate(sx, sy);
    ctx.rotate(-tag.yaw);
    ctx.fillStyle = color;
    ctx.fillRect(-3, -half, 6, half * 2);
    ctx.strokeStyle = color;
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(3, 0);
    ctx.lineTo(16, 0);
    ctx.stroke();
    ctx.restore();
    this.#label(tag.label ?? `#${tag.marker_id}`, sx + 9, sy + 16, color);
  }

  #label(text, sx, sy, color) {
    const ctx = this.ctx;
    ctx.save();
    ctx.font = "600 11px system-ui, sans-serif";
    ctx.lineWidth = 3;
    ctx.strokeStyle = "rgba(255,255,255,0.9)";
    ctx.strokeText(text, sx, sy);
    ctx.fillStyle = color;
    ctx.fillText(text, sx, sy);
    ctx.restore();
  }

  #drawDragPreview() {
    if (!this.tool || !this.drag) return;
    const pose = this.#dragPose(this.drag.world, this.drag.last);
    const colors = { goal: COLORS.goal, initialpose: COLORS.initialpose, tag: COLORS.selected };
    this.#drawArrow(pose, colors[this.tool] || COLORS.goal);
  }

  #drawScaleBar() {
    const ctx = this.ctx;
    const box = this.#size();
    const metres = niceLength(90 / this.view.scale);
    const pixels = metres * this.view.scale;
    const x = box.width - pixels - 16;
    const y = box.height - 18;
    ctx.save();
    ctx.fillStyle = "rgba(255,255,255,0.85)";
    ctx.fillRect(x - 8, y - 18, pixels + 16, 28);
    ctx.strokeStyle = "#1c2333";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(x, y - 4);
    ctx.lineTo(x, y);
    ctx.lineTo(x + pixels, y);
    ctx.lineTo(x + pixels, y - 4);
    ctx.stroke();
    ctx.fillStyle = "#1c2333";
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillText(metres >= 1 ? `${metres} m` : `${Math.round(metres * 100)} cm`, x, y - 7);
    ctx.restore();
  }
}

/** The largest of 1, 2, 5 times a power of ten not above `limit`. */
function niceLength(limit) {
  const power = 10 ** Math.floor(Math.log10(limit));
  return [5, 2, 1].map((step) => step * power).find((value) => value <= limit) || power;
}
