// A building's members, for its admins: who may use the building (their role comes from
// their group and applies to every building they are a member of); add one by username,
// remove one. The whole list is saved with PATCH /api/buildings/{b}/ {members}.

import { ApiError, api } from "./api.js";
import { el } from "./page.js";

const $ = (id) => document.getElementById(id);

export class MembersPanel {
  constructor(building) {
    this.url = `/api/buildings/${encodeURIComponent(building)}/`;
    this.members = [];
    $("member-form").addEventListener("submit", (event) => {
      event.preventDefault();
      const name = $("member-name").value.trim();
      if (name && !this.members.includes(name)) this.#save([...this.members, name]).then(() => { $("member-name").value = ""; }, () => {});
    });
  }

  async load() {
    this.#show((await api.get(this.url)).members);
  }

  async #save(members) {
    try {
      this.#show((await api.patch(this.url, { members })).members);
      $("member-error").hidden = true;
    } catch (error) {
      $("member-error").hidden = false;
      $("member-error").textContent = error instanceof ApiError ? error.messages.join(" ") : error.message;
      throw error;
    }
  }

  #show(members) {
    this.members = [...members].sort();
    $("member-rows").replaceChildren(...this.members.map((name) => el("tr", { dataset: { member: name } },
      el("td", {}, el("strong", {}, name)),
      el("td", { class: "num" }, el("button", {
        class: "btn small", type: "button", dataset: { action: "remove" },
        onclick: () => this.#save(this.members.filter((other) => other !== name)).catch(() => {}),
      }, "Remove")))));
  }
}
