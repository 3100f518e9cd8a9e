// Sub-map upload: the free, occupied and unknown cells are computed here from the chosen
// files, with the rule the server applies, and shown before anything is stored.

import { ApiError, api, urls } from "./api.js";
import { quaternionOfYaw } from "./geometry.js";
import { decodeImage, occupancyGrid, parseMapYaml, readZip } from "./mapfile.js";
import { MapView } from "./mapview.js";
import { el, pageConfig } from "./page.js";

const $ = (id) => document.getElementById(id);
const config = pageConfig();
const form = $("upload-form");
const view = new MapView($("preview-canvas"));
let kind = "pair";

async function readFile(input) {
  const file = input.files[0];
  return file ? { name: file.name, bytes: new Uint8Array(await file.arrayBuffer()) } : null;
}

/** {yaml text, image name and bytes} of the chosen files, or null while some are missing. */
async function chosenPair() {
  if (kind === "archive") {
    const archive = await readFile(form.archive);
    if (!archive) return null;
    const files = await readZip(archive.bytes);
    const yamlName = Object.keys(files).find((name) => /\.ya?ml$/i.test(name));
    if (!yamlName) throw new Error("the archive holds no YAML file");
    const yaml = new TextDecoder().decode(files[yamlName]);
    const imageName = parseMapYaml(yaml).image.split("/").pop();
    if (!files[imageName]) throw new Error(`the archive has no ${imageName}, which the YAML names`);
    return { yaml, image: { name: imageName, bytes: files[imageName] } };
  }
  const [image, yaml] = await Promise.all([readFile(form.image), readFile(form.yaml)]);
  if (!image || !yaml) return null;
  return { yaml: new TextDecoder().decode(yaml.bytes), image };
}

async function preview() {
  notify("", "");
  try {
    const pair = await chosenPair();
    if (!pair) return;
    const meta = parseMapYaml(pair.yaml);
    const grid = occupancyGrid(await decodeImage(pair.image.name, pair.image.bytes), meta);
    const [x, y, yaw] = meta.origin;
    grid.info.origin = { position: { x, y, z: 0 }, orientation: quaternionOfYaw(yaw) };
    view.setGrid(grid);
    $("preview-empty").hidden = true;
    showCounts(grid);
    showMeta(meta, grid.info);
  } catch (error) {
    notify("error", `No preview: ${error.message}`);
  }
}

function showCounts(grid) {
  const total = grid.info.width * grid.info.height;
  const box = $("preview-counts");
  const percent = (n) => `${((100 * n) / total).toFixed(1)}%`;
  const item = (label, n, color) => el("span", { class: `count-${label}` }, el("i", { class: "swatch", style: `background:${color};border:1px solid #ccc` }), `${label} `, el("strong", {}, n.toLocaleString()), ` (${percent(n)})`);
  const { free, occupied, unknown, other } = grid.counts;
  Object.assign(box.dataset, { free, occupied, unknown, other });
  box.replaceChildren(
    item("free", free, "#fff"), item("occupied", occupied, "#1c2333"), item("unknown", unknown, "#c9ced9"),
    other ? item("scaled", other, "#8f96a3") : null,
  );
}

function showMeta(meta, info) {
  $("preview-size").textContent = `${info.width}×${info.height} cells · ${(info.width * meta.resolution).toFixed(2)} × ${(info.height * meta.resolution).toFixed(2)} m`;
  const rows = [
    ["resolution", `${meta.resolution} m`], ["origin", meta.origin.join(", ")], ["mode", meta.mode],
    ["occupied ≥", meta.occupied_thresh], ["free ≤", meta.free_thresh], ["negate", meta.negate ? "yes" : "no"],
  ];
  $("preview-meta").replaceChildren(...rows.flatMap(([key, value]) => [el("dt", {}, key), el("dd", {}, String(value))]));
}

function notify(kindOf, text, lines = [], link = null) {
  $("upload-messages").replaceChildren(...(text ? [el("div", { class: `alert ${kindOf}`, role: "status" }, text, link,
    lines.length ? el("ul", {}, ...lines.map((line) => el("li", {}, line))) : null)] : []));
}

async function submit(event) {
  event.preventDefault();
  const body = new FormData();
  body.append("code", form.code.value);
  if (form.name.value) body.append("name", form.name.value);
  const fields = kind === "archive" ? ["archive"] : ["image", "yaml"];
  for (const field of fields) if (form[field].files[0]) body.append(field, form[field].files[0]);
  try {
    const stored = await api.post(urls.submaps(config.building), body);
    const href = `/buildings/${config.building}/maps/${stored.code}/`;
    notify("ok", `Stored ${stored.map_id}. `, [], el("a", { href, id: "stored-link" }, "Open it"));
  } catch (error) {
    notify("error", "The server refused this sub-map:", error instanceof ApiError ? error.messages : [error.message]);
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
for (const name of ["image", "yaml", "archive"]) form[name].addEventListener("change", preview);
form.addEventListener("submit", submit);
