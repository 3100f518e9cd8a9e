// A building's parking spots on its floor plan (where robots wait out of the others' way):
// a marker each, with the list beside. Members see them; admins choose Parking and tap the
// plan to place one, drag a marker to move it and delete from the list. Leaflet's markers
// drag with a mouse or a finger, so a phone edits them too.

import * as L from "../vendor/leaflet.js";
import { api, urls } from "./api.js";
import { el } from "./page.js";

export class ParkingSpots {
  /** `plan` (FloorPlan), `building` (code), `editable` (an admin's page), `list` (a
   * tbody), `empty` (shown with no spots), `hint(text)` (what the page says). */
  constructor({ plan, building, editable, list, empty, hint }) {
    Object.assign(this, { plan, building, editable, list, empty, hint });
    this.markers = new Map(); // id -> [spot, marker]
    this.layer = L.layerGroup().addTo(plan.map);
  }

  async load() {
    for (const spot of await api.get(urls.parking(this.building))) this.#show(spot);
    this.#render();
  }

  /** Place a new spot at `pose` of sub-map `map` (null: outside every sub-map). */
  async place({ pose, map }) {
    if (!map) {
      this.hint("That point is outside every sub-map: no parking spot placed.");
      return;
    }
    const body = { name: this.#freeName(), map, x: round(pose.x), y: round(pose.y), yaw: round(pose.yaw) };
    try {
      this.#show(await api.post(urls.parking(this.building), body));
      this.hint(`Parking spot ${body.name} placed in ${map}.`);
    } catch (error) {
      this.hint(`No parking spot placed: ${error.message}`);
    }
    this.#render();
  }

  async #move(id, marker) {
    const [spot] = this.markers.get(id);
    const { lat, lng } = marker.getLatLng();
    try {
      this.#show(await api.patch(urls.parkingSpot(this.building, id), { x: round(lng), y: round(lat) }));
      this.hint(`Parking spot ${spot.name} moved.`);
    } catch (error) {
      marker.setLatLng([spot.y, spot.x]); // back where the server has it
      this.hint(`Parking spot ${spot.name} not moved: ${error.message}`);
    }
    this.#render();
  }

  async #remove(id) {
    const [spot, marker] = this.markers.get(id);
    try {
      await api.delete(urls.parkingSpot(this.building, id));
    } catch (error) {
      this.hint(`Parking spot ${spot.name} not deleted: ${error.message}`);
      return;
    }
    marker.remove();
    this.markers.delete(id);
    this.hint(`Parking spot ${spot.name} deleted.`);
    this.#render();
  }

  #show(spot) {
    const held = this.markers.get(spot.id);
    if (held) {
      held[0] = spot;
      held[1].setLatLng([spot.y, spot.x]);
      return;
    }
    const icon = L.divIcon({ className: "parking-spot", html: "P", iconSize: [26, 26] });
    const marker = L.marker([spot.y, spot.x], { icon, draggable: this.editable, title: spot.name, keyboard: false });
    marker.on("dragend", () => this.#move(spot.id, marker));
    marker.addTo(this.layer);
    marker.getElement()?.setAttribute("data-spot", spot.name);
    this.markers.set(spot.id, [spot, marker]);
  }

  #render() {
    const spots = [...this.markers.values()].map(([spot]) => spot).sort((a, b) => a.name.localeCompare(b.name, undefined, { numeric: true }));
    this.list.replaceChildren(...spots.map((spot) => this.#row(spot)));
    this.empty.hidden = spots.length > 0;
    this.plan.element.dataset.parking = spots.map((s) => s.name).join(",");
  }

  #row(spot) {
    const remove = this.editable
      ? el("button", { class: "btn small ghost", type: "button", title: `Delete ${spot.name}`, onclick: () => this.#remove(spot.id) }, "Delete")
      : "";
    return el("tr", { dataset: { spot: spot.name } },
      el("td", {}, el("strong", {}, spot.name)),
      el("td", { class: "mono muted" }, `${spot.map} · ${spot.x.toFixed(2)}, ${spot.y.toFixed(2)}`),
      el("td", {}, remove));
  }

  #freeName() {
    const taken = new Set([...this.markers.values()].map(([spot]) => spot.name));
    let n = 1;
    while (taken.has(`P${n}`)) n += 1;
    return `P${n}`;
  }
}

function round(value) {
  return Math.round(value * 1000) / 1000;
}
