// Unmodified roslib 2.x (npm) under Node against the live CloudNav server.
//
// Usage: node tests/js/roslib_scenarios.mjs NAME ARGS_JSON
// ARGS_JSON: {url, token, cookie, origin}. Prints the scenario's findings as one JSON line;
// exits non-zero (with the reason on stderr) on failure or after WAIT_MS.
//
// Robots connect with ?token= as roslib would on a robot. The operator is a browser user:
// Node has no cookie jar, so its socket carries the session cookie and origin a browser
// would send, through roslib's public transportFactory option.

import { AbstractTransport, Action, Param, Ros, Service, Topic } from "roslib";
import WebSocket from "ws";

const WAIT_MS = 10000;
const POSE = { header: { frame_id: "boccioni_1/Hall" }, pose: { position: { x: 1, y: 2 } } };

class BrowserLikeTransport extends AbstractTransport {
  constructor(socket) {
    super();
    this.socket = socket;
    socket.onopen = (event) => this.emit("open", event);
    socket.onclose = (event) => this.emit("close", event);
    socket.onerror = (event) => this.emit("error", event);
    socket.onmessage = (event) => this.handleRawMessage(event.data);
  }
  send(message) { this.socket.send(JSON.stringify(message)); }
  close() { this.socket.close(); }
  isConnecting() { return this.socket.readyState === WebSocket.CONNECTING; }
  isOpen() { return this.socket.readyState === WebSocket.OPEN; }
  isClosing() { return this.socket.readyState === WebSocket.CLOSING; }
  isClosed() { return this.socket.readyState === WebSocket.CLOSED; }
}

function connect(args, who) {
  const options = who === "operator"
    ? {
        url: args.url,
        transportFactory: async (url) => {
          const socket = new WebSocket(url, { headers: { Cookie: args.cookie, Origin: args.origin } });
          socket.binaryType = "arraybuffer";
          return new BrowserLikeTransport(socket);
        },
      }
    : { url: `${args.url}?token=${args.token}` };
  const ros = new Ros(options);
  return new Promise((resolve, reject) => {
    ros.on("connection", () => resolve(ros));
    ros.on("error", (error) => reject(new Error(`${who} could not connect: ${error?.message ?? error}`)));
  });
}

const promised = (start) => new Promise((resolve, reject) => start(resolve, reject));
const call = (ros, name, type, request) =>
  promised((resolve, reject) =>
    new Service({ ros, name, serviceType: type }).callService(request, resolve, reject));


const scenarios = {
  async pubsub(args) {
    const robot = await connect(args, "robot");
    const operator = await connect(args, "operator");
    const plain = new Topic({ ros: operator, name: "/r1/pose", messageType: "geometry_msgs/PoseStamped" });
    const packed = new Topic({ ros: operator, name: "/r1/pose", messageType: "geometry_msgs/PoseStamped", compression: "cbor" });
    const got = { plain: null, cbor: null };
    const both = promised((resolve) => {
      const check = () => got.plain && got.cbor && resolve();
      plain.subscribe((message) => { got.plain = message; check(); });
      packed.subscribe((message) => { got.cbor = message; check(); });
    });
    await call(operator, "/rosapi/get_time", "rosapi/GetTime", {});
    new Topic({ ros: robot, name: "pose", messageType: "geometry_msgs/PoseStamped" }).publish(POSE);
    await both;
    return got;
  },

  async rosapi(args) {
    const robot = await connect(args, "robot");
    const operator = await connect(args, "operator");
    new Topic({ ros: robot, name: "map_id", messageType: "std_msgs/String" }).publish({ data: "m" });
    await promised((resolve, reject) => new Param({ ros: robot, name: "max_speed" }).set(0.5, resolve, reject));
    return {
      topics: await promised((resolve, reject) => operator.getTopics(resolve, reject)),
      services: await promised((resolve, reject) => operator.getServices(resolve, reject)),
      nodes: await promised((resolve, reject) => operator.getNodes(resolve, reject)),
      param: await promised((resolve, reject) => new Param({ ros: operator, name: "/r1/max_speed" }).get(resolve, reject)),
      time: await call(operator, "rosapi/get_time", "rosapi/GetTime", {}),
    };
  },

  async cloud_service(args) {
    const operator = await connect(args, "operator");
    return { response: await call(operator, "/cloudnav/teleop_lock", "cloudnav/TeleopLock", { robot: "r1", action: "acquire" }) };
  },

  async advertised_service(args) {
    const robot = await connect(args, "robot");
    const operator = await connect(args, "operator");
    const requests = [];
    await new Service({ ros: robot, name: "dock", serviceType: "std_srvs/SetBool" }).advertise((request, response) => {
      requests.push(request);
      response.success = true;
      response.message = "docked";
      return true;
    });
    await call(robot, "/rosapi/get_time", "rosapi/GetTime", {});
    const response = await call(operator, "/r1/dock", "std_srvs/SetBool", { data: true });
    return { requests, response };
  },

  async action(args) {
    const robot = await connect(args, "robot");
    const operator = await connect(args, "operator");
    const server = new Action({ ros: robot, name: "navigate", actionType: "nav2_msgs/action/NavigateToPose" });
    const goals = [];
    server.advertise((goal, id) => {
      goals.push(goal);
      server.sendFeedback(id, { distance_remaining: 2.0 });
      server.setSucceeded(id, { reached: true });
    });
    await call(robot, "/rosapi/get_time", "rosapi/GetTime", {});
    const feedback = [];
    const client = new Action({ ros: operator, name: "/r1/navigate", actionType: "nav2_msgs/action/NavigateToPose" });
    const result = await promised((resolve, reject) =>
      client.sendGoal({ pose: POSE }, resolve, (message) => feedback.push(message), reject));
    return { goals, feedback, result };
  },
};

const [name, raw] = process.argv.slice(2);
const timer = setTimeout(() => { console.error(`scenario ${name} timed out`); process.exit(2); }, WAIT_MS);
try {
  const found = await scenarios[name](JSON.parse(raw));
  console.log(JSON.stringify(found));
  clearTimeout(timer);
  process.exit(0);
} catch (error) {
  console.error(error?.stack ?? String(error));
  process.exit(1);
}
