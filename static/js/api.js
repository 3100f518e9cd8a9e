// The REST API from the browser: JSON in and out, Django's CSRF token, readable errors.

function csrfToken() {
  const match = document.cookie.match(/(?:^|;\s*)csrftoken=([^;]+)/);
  return match ? decodeURIComponent(match[1]) : "";
}

/** An API answer that was not 2xx; `messages` lists "field: reason" lines. */
export class ApiError extends Error {
  constructor(status, body) {
    const messages = errorMessages(body);
    super(messages.join("; ") || `HTTP ${status}`);
    this.status = status;
    this.body = body;
    this.messages = messages;
  }
}

/** Flatten DRF's error body ({field: [reasons]} or {detail}) into lines. */
export function errorMessages(body, prefix = "") {
  if (body === null || body === undefined) return [];
  if (typeof body === "string") return [prefix ? `${prefix}: ${body}` : body];
  if (Array.isArray(body)) return body.flatMap((item) => errorMessages(item, prefix));
  return Object.entries(body).flatMap(([key, value]) => {
    const label = key === "detail" || key === "non_field_errors" ? prefix : prefix ? `${prefix}.${key}` : key;
    return errorMessages(value, label);
  });
}

async function request(method, url, body, headers = {}) {
  const init = { method, headers: { Accept: "application/json", ...headers }, credentials: "same-origin" };
  if (method !== "GET") init.headers["X-CSRFToken"] = csrfToken();
  if (body instanceof FormData) init.body = body;
  else if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const response = await fetch(url, init);
  const text = await response.text();
  const data = text ? parseJson(text) : null;
  if (!response.ok) throw new ApiError(response.status, data);
  return data;
}

function parseJson(text) {
  try {
    return JSON.parse(text);
  } catch {
    return text;
  }
}

/** GET a binary answer (a 3D map's feed) as an ArrayBuffer; ApiError when refused. */
async function bytes(url) {
  const response = await fetch(url, { credentials: "same-origin" });
  if (!response.ok) throw new ApiError(response.status, parseJson(await response.text()));
  return response.arrayBuffer();
}

export const api = {
  get: (url) => request("GET", url),
  bytes,
  post: (url, body) => request("POST", url, body),
  put: (url, body) => request("PUT", url, body),
  patch: (url, body) => request("PATCH", url, body),
  delete: (url) => request("DELETE", url),
};

export const urls = {
  fleet: () => "/api/fleet/",
  buildings: () => "/api/buildings/",
  submaps: (b) => `/api/buildings/${b}/maps/`,
  submap: (b, m) => `/api/buildings/${b}/maps/${m}/`,
  grid: (b, m) => `/api/buildings/${b}/maps/${m}/grid`,
  versions: (b, m) => `/api/buildings/${b}/maps/${m}/versions/`,
  versionGrid: (b, m, n) => `/api/buildings/${b}/maps/${m}/versions/${n}/grid`,
  rollback: (b, m, n) => `/api/buildings/${b}/maps/${m}/versions/${n}/rollback`,
  compare: (b, m, from, to) => `/api/buildings/${b}/maps/${m}/versions/compare?from=${from}&to=${to}`,
  keyframes: (b, m) => `/api/buildings/${b}/maps/${m}/keyframes`,
  topology: (b) => `/api/buildings/${b}/topology`,
  validation: (b) => `/api/buildings/${b}/topology/validation`,
  route: (b, from, to) =>
    `/api/buildings/${b}/route?from=${encodeURIComponent(from)}&to=${encodeURIComponent(to)}`,
  tags: (b, m) => `/api/tags/?building=${b}${m ? `&map=${m}` : ""}`,
  tag: (id) => `/api/tags/${id}/`,
  parking: (b) => `/api/buildings/${b}/parking/`,
  parkingSpot: (b, id) => `/api/buildings/${b}/parking/${id}/`,
  newTag: () => "/api/tags/",
  tagPrint: (id, ext) => `/api/tags/${id}/print.${ext}`,
  tagSheet: (b) => `/api/buildings/${b}/tags/print.pdf`,
};

/** A robot's map_id message, "building/code@v3" (or a plain Map ID): { mapId, version }. */
export function splitMapRef(text) {
  const plain = (text || "").trim();
  const match = /^([^@\s]+)@v([1-9][0-9]*)$/.exec(plain);
  return match ? { mapId: match[1], version: Number(match[2]) } : { mapId: plain, version: null };
}

/** Split a Map ID "building/map" into its parts; a version held ("building/map@v2", as a
 * robot's map_id topic says it) is not part of the sub-map's code. */
export function splitMapId(mapId) {
  const plain = splitMapRef(mapId).mapId;
  const at = plain.indexOf("/");
  return at < 0 ? [null, plain || null] : [plain.slice(0, at), plain.slice(at + 1)];
}
