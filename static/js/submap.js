// A sub-map's page: its occupancy grid with its tags; admins place a tag by pressing on
// the map and dragging its heading, then save, move, delete or print it.

import { ApiError, api, urls } from "./api.js";
import { degrees } from "./geometry.js";
import { MapView } from "./mapview.js";
import { el, fixed, pageConfig } from "./page.js";
import { ChangesPanel } from "./changes.js";
import { VersionsPanel } from "./versions.js";

const $ = (id) => document.getElementById(id);
const config = pageConfig();
const editable = config.role === "admin";
const form = $("tag-form");
const state = { tags: [], selected: null, buildingTags: [] };

const view = new MapView($("map-canvas"), {
  onPose: (tool, pose) => placeTag(pose),
  onClick: (world, screen) => selectNear(screen),
  onHover: ({ x, y }) => { $("map-cursor").textContent = `${x.toFixed(2)}, ${y.toFixed(2)} m`; },
});
const versions = new VersionsPanel({
  building: config.building, map: config.map, editable, view, onChanged: () => loadGrid(),
});
const changes = new ChangesPanel({
  building: config.building, map: config.map, editable, versions, onChanged: () => loadGrid(),
});
window.cloudnav = { ...(window.cloudnav || {}), submapPage: { view, state, versions, changes } };

async function load() {
  const [, buildingTags] = await Promise.all([loadGrid(), api.get(urls.tags(config.building)), versions.load()]);
  await changes.load();
  setTags(buildingTags);
  await loadCoverage();
  if (editable && !state.selected) newTag();
}

async function loadGrid() {
  view.setGrid(await api.get(urls.grid(config.building, config.map)));
  $("map-wrap").dataset.loaded = config.map;
}

/** The visual map's coverage: every keyframe pose of this sub-map, drawn on the map. */
async function loadCoverage() {
  const { keyframes } = await api.get(urls.keyframes(config.building, config.map));
  view.set("keyframes", keyframes);
  $("keyframe-count").textContent = `${keyframes.length} keyframe${keyframes.length === 1 ? "" : "s"}`;
  $("keyframe-count").dataset.count = keyframes.length;
}

$("keyframes-reload")?.addEventListener("click", () => loadCoverage());
$("keyframes-clear")?.addEventListener("click", async () => {
  if (!window.confirm("Remove every keyframe of this sub-map? Robots will have to drive it again.")) return;
  await api.delete(urls.keyframes(config.building, config.map));
  await loadCoverage();
});

function setTags(buildingTags) {
  state.buildingTags = buildingTags;
  state.tags = buildingTags.filter((tag) => tag.submap === config.map);
  drawTags();
  renderList();
}

function drawTags(draft = null) {
  const tags = state.tags.map((tag) => ({
    ...tag,
    label: `#${tag.marker_id} → ${tag.links_to}`,
    selected: state.selected?.id === tag.id,
  }));
  if (draft) tags.push({ ...draft, label: `#${draft.marker_id} (new)`, selected: true });
  view.set("tags", tags);
}

function renderList() {
  const rows = state.tags.map((tag) => el("tr", { class: "clickable", dataset: { tag: tag.id }, onclick: () => select(tag) },
    el("td", { class: "num" }, `#${tag.marker_id}`),
    el("td", {}, `→ ${tag.links_to}`),
    el("td", { class: "num mono" }, `${fixed(tag.x)}, ${fixed(tag.y)}, ${fixed(degrees(tag.yaw), 0)}°`)));
  $("tag-list").replaceChildren(...(rows.length ? rows : [el("tr", {}, el("td", { class: "muted" }, "No tags in this sub-map."))]));
}

function selectNear(screen) {
  const near = state.tags
    .map((tag) => ({ tag, at: view.toScreen(tag.x, tag.y) }))
    .map(({ tag, at }) => ({ tag, distance: Math.hypot(at.sx - screen.sx, at.sy - screen.sy) }))
    .filter(({ distance }) => distance < 14)
    .sort((a, b) => a.distance - b.distance)[0];
  if (near) select(near.tag);
}

function select(tag) {
  state.selected = tag;
  fillForm(tag);
  $("tag-title").textContent = `Tag #${tag.marker_id}`;
  $("tag-payload").textContent = tag.payload ? `QR: ${tag.payload}` : "";
  for (const [id, ext] of [["tag-png", "png"], ["tag-pdf", "pdf"]]) {
    $(id).href = urls.tagPrint(tag.id, ext);
    $(id).hidden = false;
  }
  if (editable) $("tag-delete").hidden = false;
  notify("", "");
  drawTags();
}

function newTag() {
  state.selected = null;
  const used = state.buildingTags.map((tag) => tag.marker_id);
  const other = config.submaps.find((code) => code !== config.map) || config.map;
  fillForm({ marker_id: used.length ? Math.max(...used) + 1 : 0, links_to: other, x: "", y: "", yaw: 0, size: 0.06 });
  $("tag-title").textContent = "New tag";
  $("tag-payload").textContent = "";
  for (const id of ["tag-png", "tag-pdf", "tag-delete"]) $(id).hidden = true;
  notify("info", "Choose Place tag, then press on the map where the tag stands and drag the way it faces.");
  drawTags();
}

function fillForm(tag) {
  form.marker_id.value = tag.marker_id;
  form.links_to.value = tag.links_to;
  form.x.value = tag.x === "" ? "" : fixed(tag.x, 3);
  form.y.value = tag.y === "" ? "" : fixed(tag.y, 3);
  form.yaw_deg.value = fixed(degrees(tag.yaw), 1);
  form.size.value = tag.size;
}

function formTag() {
  return {
    building: config.building,
    submap: config.map,
    marker_id: Number(form.marker_id.value),
    links_to: form.links_to.value,
    x: Number(form.x.value),
    y: Number(form.y.value),
    yaw: (Number(form.yaw_deg.value) * Math.PI) / 180,
    size: Number(form.size.value),
  };
}

function placeTag(pose) {
  form.x.value = fixed(pose.x, 3);
  form.y.value = fixed(pose.y, 3);
  form.yaw_deg.value = fixed(degrees(pose.yaw), 1);
  togglePlacing(false);
  showDraft();
  notify("info", state.selected ? "Moved: save to keep the new pose." : "Placed: save to store the tag.");
}

function showDraft() {
  if (form.x.value === "" || form.y.value === "") return;
  const draft = formTag();
  if (state.selected) {
    state.tags = state.tags.map((tag) => (tag.id === state.selected.id ? { ...tag, ...draft } : tag));
    drawTags();
  } else drawTags(draft);
}

function togglePlacing(on = view.tool !== "tag") {
  view.setTool(on ? "tag" : null);
  $("place-tag").classList.toggle("active", on);
  $("map-hint").hidden = !on;
  $("map-hint").textContent = "Press where the tag stands; drag the way it faces.";
}

function notify(kind, text, lines = []) {
  const box = $("tag-messages");
  box.replaceChildren(...(text ? [el("div", { class: `alert ${kind}`, role: "status" }, text,
    lines.length ? el("ul", {}, ...lines.map((line) => el("li", {}, line))) : null)] : []));
}

async function save(event) {
  event.preventDefault();
  try {
    const body = formTag();
    const stored = state.selected
      ? await api.patch(urls.tag(state.selected.id), body)
      : await api.post(urls.newTag(), body);
    setTags(await api.get(urls.tags(config.building)));
    select(state.tags.find((tag) => tag.id === stored.id) || stored);
    notify("ok", `Tag #${stored.marker_id} saved.`);
  } catch (error) {
    notify("error", "The tag was not saved:", error instanceof ApiError ? error.messages : [error.message]);
  }
}

async function remove() {
  if (!state.selected || !window.confirm(`Delete tag #${state.selected.marker_id}?`)) return;
  await api.delete(urls.tag(state.selected.id));
  setTags(await api.get(urls.tags(config.building)));
  newTag();
}

function bindEditor() {
  $("place-tag").addEventListener("click", () => togglePlacing());
  $("tag-new").addEventListener("click", newTag);
  $("tag-delete").addEventListener("click", remove);
  form.addEventListener("submit", save);
  form.addEventListener("input", showDraft);
}

$("map-fit").addEventListener("click", () => view.fit());
if (editable) bindEditor();
load();
