// The pages' own rosbridge connection (static/js/ros.js: roslib 2.x, its reconnection with
// back-off and its subscriptions renewed on every reconnect), unmodified, under Node, as an
// operator's open browser tab: it never reloads.
//
// Usage: node tests/js/page_connection.mjs ARGS_JSON
// ARGS_JSON: {url, cookie, origin, topic, type, header}. Prints one JSON line per event:
// {"connected": the value of the front's `header` naming the process reached},
// {"disconnected": ms before the next try}, {"message": a message of `topic`}. Runs until
// killed.

import WebSocket from "ws";
import { Connection } from "../../static/js/ros.js";

const args = JSON.parse(process.argv[2]);
let upstream = "";

// The browser's WebSocket as the page meets it: a browser sends the session cookie and
// the page's origin on every handshake (Node has no cookie jar).
class BrowserWebSocket extends WebSocket {
  constructor(url) {
    super(url, { headers: { Cookie: args.cookie, Origin: args.origin } });
    this.on("upgrade", (response) => { upstream = response.headers[args.header.toLowerCase()] ?? ""; });
  }
}
globalThis.WebSocket = BrowserWebSocket;

const say = (event) => process.stdout.write(`${JSON.stringify(event)}\n`);
const connection = new Connection(args.url);
connection.addEventListener("connected", () => say({ connected: upstream }));
connection.addEventListener("disconnected", (event) => say({ disconnected: event.detail.retryInMs }));
connection.subscribe(args.topic, args.type, (message) => say({ message }));
connection.start();
