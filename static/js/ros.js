// The page's rosbridge connection: roslib 2.x over the browser's WebSocket, with automatic
// reconnection, subscriptions and publications that survive reconnects, promised service
// calls, and a meter of the bytes and messages each topic brings (for `hz` and `bw`).

import { AbstractTransport, Ros, Service, Topic } from "../vendor/roslib.js";

const TOPIC_IN_FRAME = /"topic"\s*:\s*"([^"]+)"/;
const RETRY_MIN_MS = 500;
const RETRY_MAX_MS = 8000;

/** Counts each topic's messages and wire bytes, keeping the last `windowMs` of them. */
export class TopicMeter {
  constructor(windowMs = 10000) {
    this.windowMs = windowMs;
    this.topics = new Map();
  }

  record(topic, bytes, now = performance.now()) {
    let samples = this.topics.get(topic);
    if (!samples) {
      samples = [];
      this.topics.set(topic, samples);
    }
    samples.push([now, bytes]);
    this.#trim(samples, now);
  }

  #trim(samples, now) {
    let drop = 0;
    while (drop < samples.length && now - samples[drop][0] > this.windowMs) drop += 1;
    if (drop) samples.splice(0, drop);
  }

  /** Per topic: rate (Hz), bandwidth (B/s), mean size and the spread of gaps, like rostopic. */
  summary(now = performance.now()) {
    const rows = [];
    for (const [topic, samples] of this.topics) {
      this.#trim(samples, now);
      rows.push({ topic, ...describeSamples(samples, now) });
    }
    return rows.sort((a, b) => a.topic.localeCompare(b.topic));
  }
}

function describeSamples(samples, now) {
  const count = samples.length;
  const bytes = samples.reduce((sum, [, size]) => sum + size, 0);
  const gaps = samples.slice(1).map(([t], i) => t - samples[i][0]);
  const span = count > 1 ? samples[count - 1][0] - samples[0][0] : 0;
  const rate = count > 1 && span > 0 ? (count - 1) / (span / 1000) : 0;
  const elapsed = count ? Math.max(now - samples[0][0], 1) / 1000 : 1;
  return {
    count,
    rate,
    bandwidth: count ? bytes / elapsed : 0,
    meanSize: count ? bytes / count : 0,
    minGap: gaps.length ? Math.min(...gaps) : null,
    maxGap: gaps.length ? Math.max(...gaps) : null,
    lastAge: count ? now - samples[count - 1][0] : null,
  };
}

/** roslib transport over the browser's WebSocket that meters every incoming frame. */
class MeteredTransport extends AbstractTransport {
  constructor(socket, meter) {
    super();
    this.socket = socket;
    socket.binaryType = "arraybuffer";
    socket.onopen = (event) => this.emit("open", event);
    socket.onclose = (event) => this.emit("close", event);
    socket.onerror = (event) => this.emit("error", event);
    socket.onmessage = (event) => this.#receive(event.data, meter);
  }

  #receive(data, meter) {
    if (typeof data === "string") {
      const match = TOPIC_IN_FRAME.exec(data.slice(0, 240));
      if (match) meter.record(match[1], data.length);
    }
    this.handleRawMessage(data);
  }

  send(message) { this.socket.send(JSON.stringify(message)); }
  close() { this.socket.close(); }
  isConnecting() { return this.socket.readyState === WebSocket.CONNECTING; }
  isOpen() { return this.socket.readyState === WebSocket.OPEN; }
  isClosing() { return this.socket.readyState === WebSocket.CLOSING; }
  isClosed() { return this.socket.readyState === WebSocket.CLOSED; }
}

export function rosbridgeUrl(location = window.location) {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  return `${scheme}//${location.host}/rosbridge`;
}

/**
 * One rosbridge connection for the page. Events: `connected`, `disconnected` (with
 * `detail.retryInMs`). Subscriptions made with `subscribe` are renewed on every reconnect.
 */
export class Connection extends EventTarget {
  constructor(url = rosbridgeUrl()) {
    super();
    this.url = url;
    this.meter = new TopicMeter();
    this.ros = null;
    this.connected = false;
    this.everConnected = false;
    this.failures = 0;
    this.subscriptions = new Set();
    this.publishers = new Map();
    this.retryTimer = null;
    this.stopped = false;
  }

  start() {
    this.stopped = false;
    this.#open();
    return this;
  }

  stop() {
    this.stopped = true;
    clearTimeout(this.retryTimer);
    this.ros?.close();
  }

  #open() {
    const meter = this.meter;
    const ros = new Ros({
      transportFactory: async (url) => new MeteredTransport(new WebSocket(url), meter),
    });
    this.ros = ros;
    ros.on("connection", () => this.#opened(ros));
    ros.on("close", () => this.#lost(ros));
    ros.on("error", () => this.#lost(ros));
    ros.connect(this.url).catch(() => this.#lost(ros));
  }

  #opened(ros) {
    if (ros !== this.ros) return;
    this.connected = true;
    this.everConnected = true;
    this.failures = 0;
    this.publishers.clear();
    for (const subscription of this.subscriptions) subscription.attach(ros);
    this.dispatchEvent(new CustomEvent("connected"));
  }

  #lost(ros) {
    if (ros !== this.ros || this.retryTimer !== null || this.stopped) return;
    this.connected = false;
    for (const subscription of this.subscriptions) subscription.detach();
    const retryInMs = Math.min(RETRY_MAX_MS, RETRY_MIN_MS * 2 ** this.failures);
    this.failures += 1;
    this.dispatchEvent(new CustomEvent("disconnected", { detail: { retryInMs } }));
    this.retryTimer = setTimeout(() => {
      this.retryTimer = null;
      ros.close();
      this.#open();
    }, retryInMs * (0.8 + Math.random() * 0.4));
  }

  /** Subscribe for as long as the page lives (or until the returned function is called). */
  subscribe(name, messageType, callback, options = {}) {
    const subscription = new Subscription(name, messageType, callback, options);
    this.subscriptions.add(subscription);
    if (this.connected) subscription.attach(this.ros);
    return () => {
      subscription.detach();
      this.subscriptions.delete(subscription);
    };
  }

  /** Publish one message; the topic is advertised once per connection. False if offline. */
  publish(name, messageType, message) {
    if (!this.connected) return false;
    let topic = this.publishers.get(name);
    if (!topic) {
      topic = new Topic({ ros: this.ros, name, messageType, reconnect_on_close: false });
      topic.advertise();
      this.publishers.set(name, topic);
    }
    topic.publish(message);
    return true;
  }

  /** Call a service; resolves with its values, rejects with the server's reason. */
  call(name, serviceType, request = {}, timeoutMs = 5000) {
    if (!this.connected) return Promise.reject(new Error("not connected"));
    const service = new Service({ ros: this.ros, name, serviceType });
    return new Promise((resolve, reject) => {
      const timer = setTimeout(() => reject(new Error(`${name} timed out`)), timeoutMs);
      const settle = (done) => (value) => {
        clearTimeout(timer);
        done(value);
      };
      service.callService(request, settle(resolve), settle((reason) => reject(asError(reason))));
    });
  }
}

function asError(reason) {
  if (reason instanceof Error) return reason;
  return new Error(typeof reason === "string" ? reason : JSON.stringify(reason));
}

class Subscription {
  constructor(name, messageType, callback, options) {
    this.name = name;
    this.messageType = messageType;
    this.callback = callback;
    this.options = options;
    this.topic = null;
  }

  attach(ros) {
    this.detach();
    this.topic = new Topic({
      ros,
      name: this.name,
      messageType: this.messageType,
      reconnect_on_close: false,
      ...this.options,
    });
    this.topic.subscribe(this.callback);
  }

  detach() {
    if (!this.topic) return;
    if (this.topic.ros.isConnected) this.topic.unsubscribe(this.callback);
    this.topic = null;
  }
}
