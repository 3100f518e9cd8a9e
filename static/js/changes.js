// A sub-map's proposed changes on its page: what the fleet's lasers saw differ from the
// current version (cells that became occupied in red, free in green, over the map), how
// many passes back it; admins edit it cell by cell, accept or reject it.

import { ApiError, api } from "./api.js";
import { askToConfirm, el } from "./page.js";

const $ = (id) => document.getElementById(id);

// What a brush makes a cell: a kind of the edit, or null (as in the version: not changed).
const BRUSHES = { occupied: "added", free: "removed", unknown: "cleared", keep: null };

/** An admin's edit of one proposal: every cell it sets ("added": occupied, "removed":
 * free, "cleared": unknown), changed stroke by stroke; each stroke can be undone. */
export class CellEdit {
  constructor(proposal) {
    this.cells = new Map(); // "row,col" -> kind
    for (const [kind, list] of [["added", proposal.added], ["removed", proposal.removed], ["cleared", proposal.unknown || []]]) {
      for (const [row, col] of list) this.cells.set(`${row},${col}`, kind);
    }
    this.strokes = [];
    this.stroke = null; // "row,col" -> the kind before this stroke (undefined: none)
  }

  set([row, col], kind) {
    const key = `${row},${col}`;
    this.stroke ??= new Map();
    if (!this.stroke.has(key)) this.stroke.set(key, this.cells.get(key));
    if (kind) this.cells.set(key, kind);
    else this.cells.delete(key);
  }

  end() {
    if (this.stroke?.size) this.strokes.push(this.stroke);
    this.stroke = null;
  }

  /** Take back the last stroke; false when there is none. */
  undo() {
    this.end();
    const last = this.strokes.pop();
    if (!last) return false;
    for (const [key, before] of last) {
      if (before) this.cells.set(key, before);
      else this.cells.delete(key);
    }
    return true;
  }

  /** The cells of each kind, as [row, col] lists. */
  lists() {
    const out = { added: [], removed: [], cleared: [] };
    for (const [key, kind] of this.cells) out[kind].push(key.split(",").map(Number));
    return out;
  }
}

export class ChangesPanel {
  /** `versions`: the page's VersionsPanel (its current version, its map view). */
  constructor({ building, map, editable, versions, onChanged }) {
    Object.assign(this, { building, map, editable, versions, onChanged });
    this.url = `/api/buildings/${building}/maps/${map}/changes/`;
    this.editing = null; // { proposal, edit, brush, last }
    if (editable) this.#bindEditor();
  }

  async load() {
    const open = await api.get(`${this.url}?state=open`);
    $("changes-list").replaceChildren(...(open.length ? open.map((p) => this.#row(p)) : [el("tr", {}, el("td", { class: "muted" }, "No change proposed."))]));
  }

  #row(proposal) {
    const passes = [...proposal.added_passes, ...proposal.removed_passes];
    const most = passes.length ? Math.max(...passes) : 0;
    const robots = [...(proposal.added_robots || []), ...(proposal.removed_robots || [])];
    const fewest = robots.length ? Math.min(...robots) : 0;
    const robotsSaid = `${proposal.robots} robot${proposal.robots === 1 ? "" : "s"} (each cell by at least ${fewest})`;
    const stale = proposal.based_on !== this.versions.current;
    const actions = el("div", { class: "row" },
      el("button", { class: "btn small", type: "button", onclick: () => this.show(proposal) }, "Show"));
    if (this.editable) {
      actions.append(
        el("button", { class: "btn small", type: "button", onclick: () => this.startEditing(proposal) }, "Edit"),
        el("button", { class: "btn small primary", type: "button", onclick: () => this.decide(proposal, "accept") }, "Accept"),
        el("button", { class: "btn small", type: "button", onclick: () => this.decide(proposal, "reject") }, "Reject"));
    }
    const unknown = proposal.unknown?.length ? `, ${proposal.unknown.length} unknown` : "";
    // One cell: the actions wrap under the figures, so a narrow column never clips them.
    return el("tr", { dataset: { proposal: proposal.id } },
      el("td", { class: "wrap" },
        el("div", {}, `${proposal.added.length} cells became occupied, ${proposal.removed.length} free${unknown}${proposal.edited ? " (edited)" : ""}`),
        el("div", { class: "small muted" }, `seen on ${proposal.passes} passes (each cell on up to ${most}) by ${robotsSaid}, ${proposal.scans} scans; made on v${proposal.based_on}${stale ? " (not current)" : ""}`),
        actions));
  }

  show(proposal) {
    this.versions.view.setCells({ added: proposal.added, removed: proposal.removed, cleared: proposal.unknown || [] });
    $("versions-diff").hidden = false;
    $("versions-diff").textContent = `Proposed: ${proposal.added.length} cells became occupied (red), ${proposal.removed.length} free (green)${proposal.unknown?.length ? `, ${proposal.unknown.length} unknown (blue)` : ""}.`;
  }

  // ---------------------------------------------------------------- editing

  #bindEditor() {
    for (const button of document.querySelectorAll("#change-editor [data-brush]")) {
      button.addEventListener("click", () => this.#choose(button.dataset.brush));
    }
    $("change-undo").addEventListener("click", () => {
      if (this.editing?.edit.undo()) this.#drawEdit();
    });
    $("change-save").addEventListener("click", () => this.save());
    $("change-cancel").addEventListener("click", () => this.stopEditing());
  }

  startEditing(proposal) {
    const view = this.versions.view;
    this.editing = { proposal, edit: new CellEdit(proposal), brush: "occupied", last: null };
    view.setPainter({ paint: (at) => this.#paint(at), end: () => this.#endStroke() });
    $("change-editor").hidden = false;
    $("change-edit-title").textContent = `Editing proposal ${proposal.id} (made on v${proposal.based_on})`;
    $("change-errors").replaceChildren();
    this.#choose("occupied");
    this.#drawEdit();
  }

  stopEditing() {
    this.versions.view.setPainter(null);
    this.editing = null;
    $("change-editor").hidden = true;
    this.versions.view.setCells(null);
  }

  #choose(brush) {
    if (!this.editing) return;
    this.editing.brush = brush;
    for (const button of document.querySelectorAll("#change-editor [data-brush]")) {
      button.setAttribute("aria-pressed", String(button.dataset.brush === brush));
    }
  }

  /** Paint every cell on the way from the stroke's last point (a fast pointer skips). */
  #paint(at) {
    const { edit, brush, last } = this.editing || {};
    if (!edit) return;
    const view = this.versions.view;
    const step = view.grid.info.resolution / 2;
    const from = last || at;
    const steps = Math.max(1, Math.ceil(Math.hypot(at.x - from.x, at.y - from.y) / step));
    for (let k = 0; k <= steps; k += 1) {
      const cell = view.cellAt({ x: from.x + ((at.x - from.x) * k) / steps, y: from.y + ((at.y - from.y) * k) / steps });
      if (cell) edit.set(cell, BRUSHES[brush]);
    }
    this.editing.last = at;
    this.#drawEdit();
  }

  #endStroke() {
    if (!this.editing) return;
    this.editing.edit.end();
    this.editing.last = null;
  }

  #drawEdit() {
    const lists = this.editing.edit.lists();
    this.versions.view.setCells(lists);
    $("change-edit-count").textContent = `${lists.added.length} occupied, ${lists.removed.length} free, ${lists.cleared.length} unknown · ${this.editing.edit.strokes.length} strokes`;
  }

  async save() {
    if (!this.editing) return;
    const { proposal, edit } = this.editing;
    const lists = edit.lists();
    try {
      await api.put(`${this.url}${proposal.id}/`, { added: lists.added, removed: lists.removed, unknown: lists.cleared });
      this.stopEditing();
      await this.load();
      $("versions-diff").hidden = false;
      $("versions-diff").textContent = `Proposal ${proposal.id} saved as edited: ${lists.added.length} occupied, ${lists.removed.length} free, ${lists.cleared.length} unknown. Accept it to publish.`;
    } catch (error) {
      const messages = error instanceof ApiError ? error.messages : [error.message];
      $("change-errors").replaceChildren(...messages.map((text) => el("div", { class: "alert error" }, text)));
    }
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
      $("changes-messages").hidden = true;
      if (this.editing?.proposal.id === proposal.id) this.stopEditing();
      this.versions.clear();
      await Promise.all([this.load(), this.versions.load()]);
      await this.onChanged();
    } catch (error) {
      // said in this card, beside the proposal refused, not in Versions
      const text = error instanceof ApiError ? error.messages.join("; ") : error.message;
      $("changes-messages").hidden = false;
      $("changes-messages").replaceChildren(el("div", { class: "alert error", role: "alert" }, `Not ${decision}ed: ${text}`));
    }
  }
}
