// Whether a robot is live, the same on every page: online means heard from (any of its
// topics, over this page's rosbridge connection) in the last few seconds. The server's
// record of a connection is not enough: a server that restarted still holds the poses of
// before, and a process that died leaves its rows looking connected for a while.

export const LIVE_FOR_MS = 3000;

/** True when `heard` (ms since the epoch, 0 for never) is within LIVE_FOR_MS of `now`. */
export function heardRecently(heard, now = Date.now()) {
  return Boolean(heard) && now - heard < LIVE_FOR_MS;
}

/** A robot's liveness in words: "online", "silent 12 s" or `never`, and its badge kind. */
export function liveness(heard, never = "no data", now = Date.now()) {
  if (heardRecently(heard, now)) return ["online", "ok"];
  if (!heard) return [never, "idle"];
  return [`silent ${Math.round((now - heard) / 1000)} s`, "idle"];
}
