// The buildings page for admins: create a building (POST /api/buildings/); the server
// makes its creator a member, and the page opens the new building.

import { ApiError, api } from "./api.js";

const $ = (id) => document.getElementById(id);

function showForm(shown) {
  $("building-form-card").hidden = !shown;
  $("building-error").hidden = true;
  if (shown) $("building-form").elements.code.focus();
}

async function create(event) {
  event.preventDefault();
  const fields = Object.fromEntries(new FormData($("building-form")));
  try {
    const building = await api.post("/api/buildings/", fields);
    window.location.href = `/buildings/${encodeURIComponent(building.code)}/`;
  } catch (error) {
    $("building-error").hidden = false;
    $("building-error").textContent = error instanceof ApiError ? error.messages.join(" ") : error.message;
  }
}

$("new-building").addEventListener("click", () => showForm(true));
$("building-cancel").addEventListener("click", () => showForm(false));
$("building-form").addEventListener("submit", create);
