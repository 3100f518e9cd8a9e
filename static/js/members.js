// A building's members and their roles here, for its admins: add one by username with a
// role, change a member's role, remove one. A role holds in this building only (one person
// may operate one building and only view another). GET/POST /api/buildings/{b}/members/,
// PATCH/DELETE /api/buildings/{b}/members/{username}/.

import { ApiError, api } from "./api.js";
import { el } from "./page.js";

const $ = (id) => document.getElementById(id);
const ROLES = ["admin", "operator", "viewer"];

export class MembersPanel {
  constructor(building) {
    this.url = `/api/buildings/${encodeURIComponent(building)}/members/`;
    $("member-form").addEventListener("submit", (event) => {
      event.preventDefault();
      const username = $("member-name").value.trim();
      if (!username) return;
      this.#change(() => api.post(this.url, { username, role: $("member-role").value }))
        .then(() => { $("member-name").value = ""; }, () => {});
    });
  }

  async load() {
    this.#show(await api.get(this.url));
  }

  #member(name) {
    return `${this.url}${encodeURIComponent(name)}/`;
  }

  async #change(call) {
    try {
      await call();
      $("member-error").hidden = true;
    } catch (error) {
      $("member-error").hidden = false;
      $("member-error").textContent = error instanceof ApiError ? error.messages.join(" ") : error.message;
      throw error;
    } finally {
      await this.load().catch(() => {});
    }
  }

  #show(members) {
    $("member-rows").replaceChildren(...members.map(({ username, role }) => {
      const choice = el("select", {
        dataset: { action: "role" }, "aria-label": `Role of ${username}`,
        onchange: () => this.#change(() => api.patch(this.#member(username), { role: choice.value })).catch(() => {}),
      }, ...ROLES.map((name) => el("option", { value: name }, name)));
      choice.value = role;
      return el("tr", { dataset: { member: username, role } },
        el("td", {}, el("strong", {}, username)),
        el("td", {}, choice),
        el("td", { class: "num" }, el("button", {
          class: "btn small", type: "button", dataset: { action: "remove" },
          onclick: () => this.#change(() => api.delete(this.#member(username))).catch(() => {}),
        }, "Remove")));
    }));
  }
}
