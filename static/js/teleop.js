// Teleoperation of one robot: the teleop lock (/cloudnav/teleop_lock), keyboard (arrows and
// WASD), an on-screen joystick (nipplejs: mouse, pen and touch), speed limits and a stop.
// Commands go out at 10 Hz while any input is held, then one zero Twist. Only commands keep
// the lock (it lapses CLOUDNAV_TELEOP_LOCK_TTL after the last one): while holding it the
// page only watches whether it still does, and says so when it lapsed or was taken.

import nipplejs from "../vendor/nipplejs.js";
import { degrees } from "./geometry.js";

const LOCK_SERVICE = "/cloudnav/teleop_lock";
const LOCK_TYPE = "cloudnav/TeleopLock";
const COMMAND_MS = 100;
const RENEW_MS = 2000;
const HELD_CHECK_MS = 1000;
const ASK_MS = 1000;
const STICK_PX = 150;
const KEYS = {
  ArrowUp: "forward", KeyW: "forward",
  ArrowDown: "back", KeyS: "back",
  ArrowLeft: "left", KeyA: "left",
  ArrowRight: "right", KeyD: "right",
};

export function twist(linear, angular) {
  return { linear: { x: linear, y: 0, z: 0 }, angular: { x: 0, y: 0, z: angular } };
}

export class Teleop extends EventTarget {
  constructor(connection, robot, elements, user = "") {
    super();
    this.connection = connection;
    this.robot = robot;
    this.label = `user:${user}`;
    this.ui = elements;
    this.holding = false;
    this.holder = "";
    this.pressed = new Set();
    this.stick = { x: 0, y: 0 };
    this.sentMoving = false;
    this.timers = [];
    this.#bind();
    connection.addEventListener("disconnected", () => this.#lost("connection lost"));
    // Whoever holds the lock is shown to everyone, not only to someone refused it.
    setInterval(() => this.#watch(), RENEW_MS);
    this.#watch();
    this.#render();
  }

  async #watch() {
    if (this.holding || !this.connection.connected) return;
    try {
      const answer = await this.#lock("status");
      if (!this.holding && answer.holder !== this.holder) {
        this.holder = answer.holder || "";
        this.#render();
      }
    } catch {
      // A lost connection is shown by the page's banner; the next tick asks again.
    }
  }

  get limits() {
    return { linear: Number(this.ui.maxLinear.value), angular: Number(this.ui.maxAngular.value) };
  }

  /** The command the inputs ask for now: [linear m/s, angular rad/s] (radians on the wire). */
  command() {
    const keys = this.pressed;
    const forward = (keys.has("forward") ? 1 : 0) - (keys.has("back") ? 1 : 0);
    const left = (keys.has("left") ? 1 : 0) - (keys.has("right") ? 1 : 0);
    const linear = clamp(forward || -this.stick.y, 1);
    const angular = clamp(left || -this.stick.x, 1);
    return [linear * this.limits.linear, angular * this.limits.angular];
  }

  /** Take the lock; held by someone else, ask them for it (it passes unless they keep it). */
  async acquire() {
    try {
      let answer = await this.#lock("acquire");
      if (!answer.success && answer.holder) answer = await this.#lock("ask");
      while (!answer.success && answer.handover_in !== undefined) {
        this.#notify(answer.message);
        await new Promise((resolve) => setTimeout(resolve, ASK_MS));
        answer = await this.#lock("ask");
      }
      this.holder = answer.holder || "";
      if (answer.success) this.#start();
      else this.#notify(answer.message || `held by ${this.holder}`);
    } catch (error) {
      this.#notify(error.message);
    }
    this.#render();
  }

  /** Keep the lock someone asks for. */
  async keep() {
    try {
      const answer = await this.#lock("refuse");
      this.#notify(answer.message);
    } catch (error) {
      this.#notify(error.message);
    }
    this.ui.keep.hidden = true;
  }

  async release() {
    this.#publish(0, 0);
    this.#stop();
    try {
      await this.#lock("release");
    } catch (error) {
      this.#notify(error.message);
    }
    this.holder = "";
    this.#render();
  }

  /**
   * While the page replays a recording it drives nothing: the lock is released and cannot
   * be taken until `replaying` is false again.
   */
  async setReplaying(replaying) {
    this.ui.acquire.disabled = replaying;
    if (replaying && this.holding) await this.release();
    this.#notify(replaying ? "Replaying a recording: teleoperation is off until you go back to live." : "");
  }

  /** Stop now: zero velocity, no input held. */
  halt() {
    this.pressed.clear();
    this.#setStick(0, 0);
    if (this.holding) this.#publish(0, 0);
    this.#render();
  }

  #lock(action) {
    return this.connection.call(LOCK_SERVICE, LOCK_TYPE, { robot: this.robot, action });
  }

  #start() {
    this.holding = true;
    this.#notify("");
    this.timers.push(setInterval(() => this.#tick(), COMMAND_MS));
    this.timers.push(setInterval(() => this.#stillHeld(), HELD_CHECK_MS));
  }

  #stop() {
    this.holding = false;
    this.timers.forEach(clearInterval);
    this.timers = [];
    this.pressed.clear();
    this.#setStick(0, 0);
  }

  #lost(reason) {
    if (!this.holding) return;
    this.#stop();
    this.holder = "";
    this.#notify(`Control released: ${reason}.`);
    this.#render();
  }

  /** Asking renews nothing: whether the lock is still ours, else why not. */
  async #stillHeld() {
    try {
      const answer = await this.#lock("status");
      if (!this.holding) return;
      if (answer.holder === this.label) {
        this.#asked(answer);
        return;
      }
      this.holder = answer.holder || "";
      this.#lost(this.holder ? `taken by ${this.holder.replace(/^user:/, "")}` : "it lapsed with no command for a while");
    } catch {
      // A lost connection is shown by the page's banner (and releases the lock).
    }
  }

  /** Someone asks for the lock: say who, and offer to keep it. */
  #asked(status) {
    const asker = status.asked_by;
    this.ui.keep.hidden = !asker;
    if (asker) this.#notify(`${asker.replace(/^user:/, "")} asks for control: it passes to them in ${Math.ceil(status.handover_in)} s unless you keep it.`);
  }

  #tick() {
    const [linear, angular] = this.command();
    const moving = linear !== 0 || angular !== 0;
    if (moving || this.sentMoving) this.#publish(linear, angular);
    this.sentMoving = moving;
    this.#renderKeys();
  }

  #publish(linear, angular) {
    this.connection.publish(`/${this.robot}/cmd_vel`, "geometry_msgs/Twist", twist(linear, angular));
    this.dispatchEvent(new CustomEvent("command", { detail: { linear, angular } }));
  }

  // ------------------------------------------------------------ inputs

  #bind() {
    const ui = this.ui;
    ui.acquire.addEventListener("click", () => this.acquire());
    ui.release.addEventListener("click", () => this.release());
    ui.keep.addEventListener("click", () => this.keep());
    for (const slider of [ui.maxLinear, ui.maxAngular]) {
      slider.addEventListener("input", () => this.#renderLimits());
    }
    window.addEventListener("keydown", (event) => this.#key(event, true));
    window.addEventListener("keyup", (event) => this.#key(event, false));
    window.addEventListener("blur", () => this.pressed.clear());
    this.#bindJoystick(ui.joystick);
    this.#renderLimits();
  }

  #key(event, down) {
    if (isTyping(event.target) || !this.holding) return; // keys drive only for the lock holder
    const direction = KEYS[event.code];
    if (event.code === "Space" && down) {
      event.preventDefault();
      this.dispatchEvent(new CustomEvent("stop"));
      return;
    }
    if (!direction) return;
    event.preventDefault();
    if (down) this.pressed.add(direction);
    else this.pressed.delete(direction);
    this.#renderKeys();
  }

  /** A static nipplejs stick in `zone`; `stick` is in screen axes (y down: back). */
  #bindJoystick(zone) {
    const sticks = nipplejs.create({
      zone, mode: "static", position: { left: "50%", top: "50%" }, size: STICK_PX,
      color: { front: "#2f6fed", back: "rgba(47, 111, 237, 0.15)" }, restOpacity: 0.9,
      // The page's cards load and grow above the stick: measure where it is on each move.
      dynamicPage: true,
    });
    sticks.on("move", ({ data }) => {
      if (this.holding) this.#setStick(data.vector.x, -data.vector.y);
    });
    sticks.on("end", () => this.#setStick(0, 0));
  }

  #setStick(x, y) {
    this.stick = { x, y };
  }

  // ------------------------------------------------------------ display

  #notify(text) {
    this.ui.message.textContent = text;
    this.ui.message.hidden = !text;
  }

  #render() {
    const ui = this.ui;
    ui.acquire.hidden = this.holding;
    ui.release.hidden = !this.holding;
    ui.joystick.classList.toggle("disabled", !this.holding);
    ui.lockState.className = `badge ${this.holding ? "ok" : this.holder ? "warn" : "idle"}`;
    ui.lockState.textContent = this.holding
      ? "You are driving"
      : this.holder ? `Driven by ${this.holder.replace(/^user:/, "")}` : "Not driving";
    this.#renderKeys();
  }

  #renderKeys() {
    for (const key of this.ui.keys.querySelectorAll("kbd[data-direction]")) {
      key.classList.toggle("on", this.pressed.has(key.dataset.direction));
    }
  }

  #renderLimits() {
    this.ui.maxLinearOut.textContent = `${Number(this.ui.maxLinear.value).toFixed(2)} m/s`;
    this.ui.maxAngularOut.textContent = `${degrees(Number(this.ui.maxAngular.value)).toFixed(0)} °/s`;
  }
}

function clamp(value, limit) {
  return Math.max(-limit, Math.min(limit, value));
}

function isTyping(target) {
  return target instanceof HTMLElement && (target.isContentEditable || ["INPUT", "SELECT", "TEXTAREA"].includes(target.tagName));
}
