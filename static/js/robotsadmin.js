// Robot administration: the registry from /api/robots/ (admins), a robot's buildings as
// checkboxes, registration and token rotation showing the token once, and revocation.

import { ApiError, api } from "./api.js";
import { askToConfirm, el, pageConfig } from "./page.js";

const $ = (id) => document.getElementById(id);
const buildings = pageConfig().buildings || [];

async function load() {
  const robots = await api.get("/api/robots/");
  $("robot-rows").replaceChildren(...(robots.length ? robots.map(row) : [el("tr", {}, el("td", { class: "muted" }, "No robots yet."))]));
}

function row(robot) {
  const boxes = buildings.map((code) => el("label", { class: "layer" },
    el("input", { type: "checkbox", checked: robot.buildings.includes(code), dataset: { building: code },
      onchange: () => assign(robot.name) }), code));
  return el("tr", { dataset: { robot: robot.name } },
    el("td", { class: "wrap" }, el("a", { href: `/robots/${encodeURIComponent(robot.name)}/` }, el("strong", {}, robot.name)),
      robot.description ? el("div", { class: "muted small" }, robot.description) : null),
    el("td", { class: "wrap buildings" }, ...boxes),
    el("td", {}, el("div", { class: "row" },
      el("button", { class: "btn small", type: "button", dataset: { action: "rotate" }, onclick: () => rotate(robot.name) }, "Rotate token"),
      el("button", { class: "btn small", type: "button", dataset: { action: "revoke" }, onclick: () => revoke(robot.name) }, "Revoke"))));
}

function showToken(title, token) {
  $("token-box").hidden = false;
  $("token-title").textContent = title;
  $("token-value").textContent = token;
}

async function assign(name) {
  const chosen = [...document.querySelectorAll(`tr[data-robot="${name}"] input[data-building]`)].filter((box) => box.checked).map((box) => box.dataset.building);
  // A robot in none of your buildings would vanish from your list: revoke it instead.
  if (!chosen.length) {
    alertOnce(`${name} needs at least one of your buildings; to take it out of service, revoke it.`);
  } else {
    await api.patch(`/api/robots/${encodeURIComponent(name)}/`, { buildings: chosen }).catch((error) => alertOnce(error.message));
  }
  await load();
}

function alertOnce(text) {
  $("register-error").hidden = false;
  $("register-error").textContent = text;
}

async function rotate(name) {
  const sure = await askToConfirm({
    id: "rotate-dialog",
    title: `Rotate the token of ${name}?`,
    text: "Its current token stops working at once: a connected robot is cut off until it is given the new one.",
    confirm: "Rotate token",
  });
  if (!sure) return;
  const answer = await api.post(`/api/robots/${encodeURIComponent(name)}/rotate_token`);
  showToken(`New token of ${name} (the old one stopped working)`, answer.token);
}

async function revoke(name) {
  const sure = await askToConfirm({
    id: "revoke-dialog",
    title: `Revoke ${name}?`,
    text: "Its registration and token are removed: it can no longer fetch maps or connect.",
    confirm: "Revoke",
  });
  if (!sure) return;
  await api.delete(`/api/robots/${encodeURIComponent(name)}/`);
  await load();
}

$("register-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const form = new FormData(event.target);
  const body = { name: form.get("name"), description: form.get("description"), buildings: form.getAll("buildings") };
  try {
    const answer = await api.post("/api/robots/", body);
    $("register-error").hidden = true;
    showToken(`Token of ${answer.name}`, answer.token);
    event.target.reset();
    await load();
  } catch (error) {
    $("register-error").hidden = false;
    $("register-error").textContent = error instanceof ApiError ? error.messages.join("; ") : error.message;
  }
});
$("token-copy").addEventListener("click", () => navigator.clipboard?.writeText($("token-value").textContent));
load();
