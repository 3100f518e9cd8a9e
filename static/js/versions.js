// A sub-map's versions on its page: who made each, when and why; compare one with the
// current version (added cells red, removed green, over the map); admins roll back.

import { ApiError, api, urls } from "./api.js";
import { ago, askToConfirm, badge, el } from "./page.js";

const $ = (id) => document.getElementById(id);

export class VersionsPanel {
  /** `view`: the page's MapView; `onChanged`: called after a rollback made a new version. */
  constructor({ building, map, editable, view, onChanged }) {
    Object.assign(this, { building, map, editable, view, onChanged });
    this.current = null;
    this.comparing = null;
  }

  async load() {
    const body = await api.get(urls.versions(this.building, this.map));
    this.current = body.current;
    $("versions-current").textContent = `v${body.current}`;
    const buried = body.buried_tags;
    $("versions-buried").hidden = !buried.length;
    $("versions-buried").textContent = buried.length
      ? `Tags standing in an occupied cell of this version: ${buried.map((id) => `#${id}`).join(", ")}. A robot cannot reach them: move them or fix the map.`
      : "";
    $("versions-list").replaceChildren(...body.versions.map((version) => this.#row(version)));
    return body;
  }

  #row(version) {
    const current = version.number === this.current;
    const actions = el("div", { class: "row" });
    if (!current) {
      actions.append(el("button", { class: "btn small", type: "button", onclick: () => this.compare(version.number) }, "Compare"));
      if (this.editable) actions.append(el("button", { class: "btn small", type: "button", onclick: () => this.rollback(version.number) }, "Roll back"));
    }
    const who = version.author || "system";
    const why = version.based_on ? `${version.reason} (from v${version.based_on})` : version.reason;
    return el("tr", { dataset: { version: version.number } },
      el("td", {},
        el("div", {}, el("strong", {}, `v${version.number}`), ` · ${why} `, current ? badge("current", "ok") : null),
        el("div", { class: "small muted", title: version.created }, `${who} · ${ago(version.created)}`),
        version.note ? el("div", { class: "small" }, version.note) : null),
      el("td", {}, actions));
  }

  /** Show how the current version differs from `number` over the map. */
  async compare(number) {
    if (this.comparing === number) return this.clear();
    try {
      const diff = await api.get(urls.compare(this.building, this.map, number, this.current));
      this.comparing = number;
      this.view.setCells(diff.cells);
      $("versions-diff").hidden = false;
      $("versions-diff").textContent = `From v${number} to v${this.current}: ${diff.added} cells became occupied (red), ${diff.removed} became free (green)${diff.truncated ? ", not all drawn" : ""}.`;
    } catch (error) {
      this.#say(error);
    }
  }

  clear() {
    this.comparing = null;
    this.view.setCells(null);
    $("versions-diff").hidden = true;
  }

  async rollback(number) {
    const ok = await askToConfirm({
      title: `Roll back to v${number}?`,
      text: "Its map becomes a new version; robots in this sub-map take it within seconds. Tags and topology stay as they are.",
      confirm: "Roll back",
      id: "rollback-dialog",
    });
    if (!ok) return;
    try {
      await api.post(urls.rollback(this.building, this.map, number), { note: `back to v${number}` });
      this.clear();
      await this.load();
      await this.onChanged();
    } catch (error) {
      this.#say(error);
    }
  }

  #say(error) {
    $("versions-diff").hidden = false;
    $("versions-diff").textContent = error instanceof ApiError ? error.messages.join("; ") : error.message;
  }
}
