// Sub-map upload: the chosen files go to the server as a dry run (its own checks and
// conversion, nothing stored), and the page draws the preview and the field errors it
// answers. Storing under a code that exists asks before replacing a live map.

import { ApiError, api, urls } from "./api.js";
import { MapView } from "./mapview.js";
import { askToConfirm, el, pageConfig } from "./page.js";

const $ = (id) => document.getElementById(id);
const config = pageConfig();
const form = $("upload-form");
const view = new MapView($("preview-canvas"));
let kind = "pair";
let asked = 0; // previews asked so far: only the latest one's answer is drawn

const fileFields = () => (kind === "archive" ? ["archive"] : ["image", "yaml"]);

/** The form's code, name and chosen files as a multipart body, with `extra` fields. */
function uploadBody(extra = {}) {
  const body = new FormData();
  if (form.code.value) body.append("code", form.code.value);
  if (form.name.value) body.append("name", form.name.value);
  for (const field of fileFields()) if (form[field].files[0]) body.append(field, form[field].files[0]);
  for (const [key, value] of Object.entries(extra)) body.append(key, value);
  return body;
}

async function preview() {
  const ticket = ++asked;
  if (fileFields().some((field) => !form[field].files[0])) {
    notify("", "");
    return;
  }
  try {
    const answer = await api.post(urls.submaps(config.building), uploadBody({ dry_run: "true" }));
    if (ticket !== asked) return;
    view.setGrid(answer.preview);
    $("preview-empty").hidden = true;
    showCounts(answer);
    showMeta(answer);
    notify(answer.replaces ? "warn" : "", answer.replaces ? `${answer.map_id} exists: storing these files will replace its map.` : "");
  } catch (error) {
    if (ticket !== asked) return;
    forgetFigures();
    notify("error", "No preview: the server would refuse these files:", errorLines(error));
  }
}

/** Clear the counts and metadata of an earlier preview, which no longer hold. */
function forgetFigures() {
  const box = $("preview-counts");
  for (const key of Object.keys(box.dataset)) delete box.dataset[key];
  box.replaceChildren();
  $("preview-meta").replaceChildren();
  $("preview-size").textContent = "";
}

function errorLines(error) {
  return error instanceof ApiError ? error.messages : [error.message];
}

function showCounts({ counts, width, height }) {
  const box = $("preview-counts");
  const percent = (n) => `${((100 * n) / (width * height)).toFixed(1)}%`;
  const item = (label, n, color) => el("span", { class: `count-${label}` }, el("i", { class: "swatch", style: `background:${color};border:1px solid #ccc` }), `${label} `, el("strong", {}, n.toLocaleString()), ` (${percent(n)})`);
  const { free, occupied, unknown, other } = counts;
  Object.assign(box.dataset, { free, occupied, unknown, other });
  box.replaceChildren(
    item("free", free, "#fff"), item("occupied", occupied, "#1c2333"), item("unknown", unknown, "#c9ced9"),
    ...(other ? [item("scaled", other, "#8f96a3")] : []),
  );
}

function showMeta(answer) {
  const { width, height, resolution } = answer;
  const shrunk = answer.preview_factor > 1 ? ` · drawn at 1:${answer.preview_factor}` : "";
  $("preview-size").textContent = `${width}×${height} cells · ${(width * resolution).toFixed(2)} × ${(height * resolution).toFixed(2)} m${shrunk}`;
  const rows = [
    ["resolution", `${resolution} m`], ["origin", answer.origin.join(", ")], ["mode", answer.mode],
    ["occupied ≥", answer.occupied_thresh], ["free ≤", answer.free_thresh], ["negate", answer.negate ? "yes" : "no"],
  ];
  $("preview-meta").replaceChildren(...rows.flatMap(([key, value]) => [el("dt", {}, key), el("dd", {}, String(value))]));
}

function notify(kindOf, text, lines = [], link = null) {
  $("upload-messages").replaceChildren(...(text ? [el("div", { class: `alert ${kindOf}`, role: "status" }, text, link,
    lines.length ? el("ul", {}, ...lines.map((line) => el("li", {}, line))) : null)] : []));
}

/** Whether to replace the live map of the form's code (the server answered 409). */
function confirmReplace() {
  const mapId = `${config.building}/${form.code.value}`;
  return askToConfirm({
    id: "replace-dialog",
    title: `Replace the map of ${mapId}?`,
    text: `${mapId} already exists. Storing these files replaces its map; robots get the new one on their next bundle request. Its tags stay.`,
    confirm: "Replace it",
    cancel: "Keep the stored map",
  });
}

async function store(extra = {}) {
  const stored = await api.post(urls.submaps(config.building), uploadBody(extra));
  const href = `/buildings/${config.building}/maps/${stored.code}/`;
  notify("ok", `Stored ${stored.map_id}. `, [], el("a", { href, id: "stored-link" }, "Open it"));
}

/** Store the form's files; the map of a code that exists is replaced only if they say so. */
async function storeAsking() {
  try {
    return await store();
  } catch (error) {
    if (!(error instanceof ApiError && error.status === 409)) throw error;
  }
  if (await confirmReplace()) return store({ replace: "true" });
  notify("info", `Not stored: ${config.building}/${form.code.value} keeps its map.`);
}

async function submit(event) {
  event.preventDefault();
  try {
    await storeAsking();
  } catch (error) {
    notify("error", "The server refused this sub-map:", errorLines(error));
  }
}

function chooseKind(next) {
  kind = next;
  for (const button of $("upload-kind").querySelectorAll("button")) button.classList.toggle("active", button.dataset.kind === kind);
  $("pair-fields").hidden = kind !== "pair";
  $("archive-fields").hidden = kind !== "archive";
  preview();
}

for (const button of $("upload-kind").querySelectorAll("button")) {
  button.addEventListener("click", () => chooseKind(button.dataset.kind));
}
for (const name of ["image", "yaml", "archive", "code"]) form[name].addEventListener("change", preview);
form.addEventListener("submit", submit);
