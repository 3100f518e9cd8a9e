// A sub-map's proposed changes on its page: what the fleet's lasers saw differ from the
// current version (cells that became occupied in red, free in green, over the map), how
// many passes back it; admins accept or reject.

import { ApiError, api } from "./api.js";
import { askToConfirm, el } from "./page.js";

const $ = (id) => document.getElementById(id);

export class ChangesPanel {
  /** `versions`: the page's VersionsPanel (its current version, its map view). */
  constructor({ building, map, editable, versions, onChanged }) {
    Object.assign(this, { building, map, editable, versions, onChanged });
    this.url = `/api/buildings/${building}/maps/${map}/changes/`;
  }

  async load() {
    const open = await api.get(`${this.url}?state=open`);
    $("changes-list").replaceChildren(...(open.length ? open.map((p) => this.#row(p)) : [el("tr", {}, el("td", { class: "muted" }, "No change proposed."))]));
  }

  #row(proposal) {
    const passes = [...proposal.added_passes, ...proposal.removed_passes];
    const most = passes.length ? Math.max(...passes) : 0;
    const stale = proposal.based_on !== this.versions.current;
    const actions = el("div", { class: "row" },
      el("button", { class: "btn small", type: "button", onclick: () => this.show(proposal) }, "Show"));
    if (this.editable) {
      actions.append(
        el("button", { class: "btn small primary", type: "button", onclick: () => this.decide(proposal, "accept") }, "Accept"),
        el("button", { class: "btn small", type: "button", onclick: () => this.decide(proposal, "reject") }, "Reject"));
    }
    return el("tr", { dataset: { proposal: proposal.id } },
      el("td", {},
        el("div", {}, `${proposal.added.length} cells became occupied, ${proposal.removed.length} free`),
        el("div", { class: "small muted" }, `seen on ${proposal.passes} passes (each cell on up to ${most}), ${proposal.scans} scans; made on v${proposal.based_on}${stale ? " (not current)" : ""}`)),
      el("td", {}, actions));
  }

  show(proposal) {
    this.versions.view.setCells({ added: proposal.added, removed: proposal.removed });
    $("versions-diff").hidden = false;
    $("versions-diff").textContent = `Proposed: ${proposal.added.length} cells became occupied (red), ${proposal.removed.length} free (green).`;
  }

  async decide(proposal, decision) {
    if (decision === "accept") {
      const ok = await askToConfirm({
        title: "Accept this change?",
        text: "It becomes the sub-map's next version; robots in this sub-map take it within seconds.",
        confirm: "Accept",
        id: "accept-dialog",
      });
      if (!ok) return;
    }
    try {
      await api.post(`${this.url}${proposal.id}/${decision}`, {});
      this.versions.clear();
      await Promise.all([this.load(), this.versions.load()]);
      await this.onChanged();
    } catch (error) {
      $("versions-diff").hidden = false;
      $("versions-diff").textContent = error instanceof ApiError ? error.messages.join("; ") : error.message;
    }
  }
}
