// A building's recording settings on its page: what its robots record (topics, camera
// rate) and what is kept (days, disk budget). Every member reads them; its admins change
// them. GET/PUT /api/buildings/{b}/recording/.

import { ApiError, api } from "./api.js";
import { el } from "./page.js";

const $ = (id) => document.getElementById(id);

export class RecordingPanel {
  constructor(building, { editable }) {
    this.url = `/api/buildings/${encodeURIComponent(building)}/recording/`;
    if (!editable) return;
    $("recording-form").addEventListener("submit", (event) => {
      event.preventDefault();
      this.#save();
    });
  }

  async load() {
    try {
      this.#show(await api.get(this.url));
    } catch (error) {
      this.#error(error);
    }
  }

  async #save() {
    $("recording-saved").textContent = "";
    try {
      this.#show(await api.put(this.url, this.#chosen()));
      $("recording-error").hidden = true;
      $("recording-saved").textContent = "Saved: robots follow within half a minute.";
    } catch (error) {
      this.#error(error);
    }
  }

  #chosen() {
    const topics = [...$("recording-topics").querySelectorAll("input:checked")].map((box) => box.value);
    return {
      enabled: $("recording-enabled").checked,
      topics,
      camera_rate: Number($("recording-camera").value),
      retention_days: Number($("recording-days").value),
      budget_mb: Number($("recording-budget").value),
    };
  }

  #show(settings) {
    $("recording-enabled").checked = settings.enabled;
    $("recording-topics").replaceChildren(...settings.recordable.map((topic) => el("label", { class: "row", style: "gap:4px" },
      el("input", { type: "checkbox", value: topic, checked: settings.topics.includes(topic), dataset: { topic } }),
      el("span", { class: "mono" }, topic))));
    $("recording-camera").value = settings.camera_rate;
    $("recording-days").value = settings.retention_days;
    $("recording-budget").value = settings.budget_mb;
  }

  #error(error) {
    $("recording-error").hidden = false;
    $("recording-error").textContent = error instanceof ApiError ? error.messages.join(" ") : error.message;
  }
}
