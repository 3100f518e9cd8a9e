// The mapping card's 3D view of a visual session: the keyframes' coloured points, the
// camera's path and the loop closures, in three.js (bundled into static/vendor by
// scripts/build_static.sh), with OrbitControls: drag to turn, right-drag or two fingers
// to pan, wheel or pinch to zoom. Each keyframe's points arrive once, in its robot's
// frame (the feed of `/points?from=`, maps/domain/visual_cloud.feed_bytes), and are
// drawn at its pose; a loop closure moves the poses, so what was drawn moves with them.

import {
  BufferAttribute,
  BufferGeometry,
  Color,
  GridHelper,
  Group,
  Line,
  LineBasicMaterial,
  LineSegments,
  OrbitControls,
  PerspectiveCamera,
  Points,
  PointsMaterial,
  Scene,
  WebGLRenderer,
} from "../vendor/three.js";
import { api } from "./api.js";

const MAX_POINTS = 2_000_000; // drawn at most: beyond, new keyframes' points are left out
const CAMERA_HEIGHT = 0.25; // metres: the path is drawn at the camera's height

export class CloudView {
  /** @param {HTMLCanvasElement} canvas */
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.scene = new Scene();
    this.scene.background = new Color(0x10141a);
    this.camera = new PerspectiveCamera(60, 1, 0.05, 200);
    this.camera.up.set(0, 0, 1); // the map's z is up
    this.camera.position.set(-4, -4, 5);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener("change", () => this.render());
    const floor = new GridHelper(20, 20, 0x445566, 0x2a323c);
    floor.rotation.x = Math.PI / 2; // GridHelper lies in x-z: stand it on the map's floor
    this.scene.add(floor);
    this.keyframes = new Group();
    this.path = new Line(new BufferGeometry(), new LineBasicMaterial({ color: 0x4fc3f7 }));
    this.loops = new LineSegments(new BufferGeometry(), new LineBasicMaterial({ color: 0xff7043 }));
    this.scene.add(this.keyframes, this.path, this.loops);
    this.material = new PointsMaterial({ size: 0.04, vertexColors: true });
    this.session = null;
    this.points = 0;
    this.framed = false;
    new ResizeObserver(() => this.#resize()).observe(canvas);
    this.#resize();
  }

  /** Draw what session `id` has mapped since the last call (a new id starts afresh). */
  async update(id) {
    if (id !== this.session) this.#clear(id);
    let more = true;
    while (more && this.session === id) {
      const feed = parseFeed(await api.bytes(`/api/mapping/sessions/${id}/points?from=${this.keyframes.children.length}`));
      if (this.session !== id) return;
      if (feed.start !== this.keyframes.children.length) {
        this.#clear(id); // the session's keyframes are not those drawn (it was resumed anew)
        continue;
      }
      this.#add(feed);
      more = feed.clouds.length > 0 && this.keyframes.children.length < feed.poses.length;
    }
    this.render();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
    this.canvas.dataset.points = String(this.points);
    this.canvas.dataset.keyframes = String(this.keyframes.children.length);
    this.canvas.dataset.pathPoints = String(vertices(this.path));
    this.canvas.dataset.loops = String(vertices(this.loops) / 2);
    // where the view looks from, for tests and the curious: turned (radians) and how far
    this.canvas.dataset.azimuth = this.controls.getAzimuthalAngle().toFixed(4);
    this.canvas.dataset.distance = this.controls.getDistance().toFixed(4);
  }

  #clear(id) {
    this.session = id;
    for (const child of [...this.keyframes.children]) {
      child.geometry.dispose();
      this.keyframes.remove(child);
    }
    this.points = 0;
    this.framed = false;
    for (const line of [this.path, this.loops]) {
      line.geometry.dispose();
      line.geometry = new BufferGeometry(); // another session's path is not this one's
    }
  }

  #add(feed) {
    for (const cloud of feed.clouds) {
      const geometry = new BufferGeometry();
      const room = this.points + cloud.count <= MAX_POINTS;
      geometry.setAttribute("position", new BufferAttribute(room ? cloud.positions : new Float32Array(0), 3));
      geometry.setAttribute("color", new BufferAttribute(room ? cloud.colours : new Uint8Array(0), 3, true));
      this.keyframes.add(new Points(geometry, this.material));
      if (room) this.points += cloud.count;
    }
    this.keyframes.children.forEach((points, index) => {
      const pose = feed.poses[index];
      if (!pose) return;
      points.position.set(pose[0], pose[1], 0);
      points.rotation.set(0, 0, pose[2]);
    });
    const at = (pose) => [pose[0], pose[1], CAMERA_HEIGHT];
    this.path.geometry.dispose();
    this.path.geometry = lineGeometry(feed.poses.flatMap(at));
    this.loops.geometry.dispose();
    this.loops.geometry = lineGeometry(
      feed.loops.flatMap(([i, j]) => (feed.poses[i] && feed.poses[j] ? [...at(feed.poses[i]), ...at(feed.poses[j])] : [])),
    );
    if (!this.framed && feed.poses.length) this.#frame(feed.poses[0]);
  }

  /** Look at the first keyframe from behind and above it, once per session. */
  #frame([x, y, yaw]) {
    this.framed = true;
    this.controls.target.set(x + 2 * Math.cos(yaw), y + 2 * Math.sin(yaw), 0.5);
    this.camera.position.set(x - 3 * Math.cos(yaw), y - 3 * Math.sin(yaw), 4);
    this.controls.update();
  }

  #resize() {
    const width = this.canvas.clientWidth || 300;
    const height = this.canvas.clientHeight || 200;
    this.renderer.setSize(width, height, false);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.render();
  }
}

/** How many points `line` joins (0 before it has any). */
function vertices(line) {
  return line.geometry.getAttribute("position")?.count ?? 0;
}

function lineGeometry(coordinates) {
  const geometry = new BufferGeometry();
  geometry.setAttribute("position", new BufferAttribute(new Float32Array(coordinates), 3));
  return geometry;
}

/**
 * The feed's binary answer (little-endian, 4-byte aligned; see feed_bytes): keyframes,
 * start, clouds, loops (int32); each keyframe's x, y, yaw (float32); each loop's i, j
 * (int32); each cloud's n (int32), n points (float32 x, y, z), n colours (uint8 r, g, b,
 * padded to 4 bytes).
 */
export function parseFeed(buffer) {
  const view = new DataView(buffer);
  const [keyframes, start, count, loopCount] = [0, 4, 8, 12].map((at) => view.getInt32(at, true));
  let offset = 16;
  const floats = (n) => {
    const out = new Float32Array(buffer.slice(offset, offset + 4 * n));
    offset += 4 * n;
    return out;
  };
  const flat = floats(3 * keyframes);
  const poses = Array.from({ length: keyframes }, (_, k) => [flat[3 * k], flat[3 * k + 1], flat[3 * k + 2]]);
  const ints = new Int32Array(buffer.slice(offset, offset + 8 * loopCount));
  offset += 8 * loopCount;
  const loops = Array.from({ length: loopCount }, (_, k) => [ints[2 * k], ints[2 * k + 1]]);
  const clouds = [];
  for (let c = 0; c < count; c++) {
    const n = view.getInt32(offset, true);
    offset += 4;
    const positions = floats(3 * n);
    const colours = new Uint8Array(buffer.slice(offset, offset + 3 * n));
    offset += Math.ceil((3 * n) / 4) * 4;
    clouds.push({ count: n, positions, colours });
  }
  return { start, poses, loops, clouds };
}
