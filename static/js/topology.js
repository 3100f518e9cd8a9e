// A building's topology graph drawn by cytoscape.js: sub-maps as nodes at their (x, y) in
// metres, edges with their costs, a route, tags no robot can cross and robots highlighted;
// pan and zoom (wheel, pinch). When editable: drag nodes, tap two nodes to join them, tap
// an edge to select it (then set its cost or remove it). The graph itself (nodes, edges)
// is this view's; cytoscape only draws it and reports gestures.

import cytoscape from "../vendor/cytoscape.js";

// Screen pixels per metre of the nodes' coordinates before fitting (cytoscape's model units).
const UNITS_PER_M = 20;
const NODE_PX = 38;
const ROBOT_PX = 14;
const COLORS = {
  surface: "#ffffff", border: "#e1e5ee", text: "#1c2333", muted: "#66708a", accent: "#2f6fed",
  accentSoft: "#e6eefe", ok: "#1f9d55", okSoft: "#e3f6ea", danger: "#d93636", warn: "#d98a00", edge: "#9aa5bf",
};

export function edgeKey(a, b) {
  return [a, b].sort().join("\u2194");
}

export class TopologyView extends EventTarget {
  constructor(element, { editable = false } = {}) {
    super();
    this.element = element;
    this.editable = editable;
    this.nodes = [];
    this.edges = [];
    this.route = [];
    this.robots = new Map();
    this.invalid = new Set();
    this.selected = null;
    this.linking = null;
    element.classList.toggle("editable", editable);
    this.cy = cytoscape({
      container: element, style: STYLE, layout: { name: "preset" }, minZoom: 0.2, maxZoom: 4,
      boxSelectionEnabled: false, autounselectify: true, autoungrabify: !editable,
    });
    this.#bind();
    new ResizeObserver(() => this.cy.resize()).observe(element);
    window.cloudnav = { ...(window.cloudnav || {}) };
    window.cloudnav.topologies = { ...(window.cloudnav.topologies || {}), [element.id]: this };
  }

  load({ nodes, edges }) {
    this.nodes = nodes.map((node) => ({ ...node }));
    this.edges = edges.map((edge) => ({ ...edge }));
    this.selected = null;
    this.linking = null;
    this.render();
    this.cy.fit(undefined, NODE_PX);
  }

  /** The graph as the topology API takes it. */
  document() {
    return {
      nodes: this.nodes.map(({ code, x, y }) => ({ code, x, y })),
      edges: this.edges.map(({ a, b, cost }) => ({ a, b, cost })),
    };
  }

  setRoute(codes) {
    this.route = codes;
    this.render();
  }

  /** `robots`: sub-map code -> robot names standing in it. */
  setRobots(robots) {
    this.robots = robots;
    this.render();
  }

  setInvalid(keys) {
    this.invalid = new Set(keys);
    this.render();
  }

  // ------------------------------------------------------------ editing

  selectedEdge() {
    return this.edges.find((edge) => edgeKey(edge.a, edge.b) === this.selected) || null;
  }

  setCost(cost) {
    const edge = this.selectedEdge();
    if (!edge) return;
    edge.cost = cost;
    this.#changed();
  }

  removeSelected() {
    this.edges = this.edges.filter((edge) => edgeKey(edge.a, edge.b) !== this.selected);
    this.selected = null;
    this.#changed();
  }

  #bind() {
    if (!this.editable) return;
    this.cy.on("tap", "node.submap", (event) => this.#tapNode(event.target.id()));
    this.cy.on("tap", "edge", (event) => {
      const key = event.target.id();
      this.selected = this.selected === key ? null : key;
      this.render();
      this.dispatchEvent(new CustomEvent("select"));
    });
    this.cy.on("drag", "node.submap", (event) => this.#moveRobots(event.target));
    this.cy.on("dragfree", "node.submap", (event) => {
      const node = this.nodes.find((n) => n.code === event.target.id());
      Object.assign(node, toMetres(event.target.position()));
      this.#changed();
    });
  }

  #tapNode(code) {
    if (!this.linking || this.linking === code) {
      this.linking = this.linking === code ? null : code;
      this.render();
      return;
    }
    const key = edgeKey(this.linking, code);
    if (!this.edges.some((edge) => edgeKey(edge.a, edge.b) === key)) {
      this.edges.push({ a: this.linking, b: code, cost: this.#distance(this.linking, code) });
    }
    this.linking = null;
    this.selected = key;
    this.#changed();
  }

  #distance(a, b) {
    const [p, q] = [a, b].map((code) => this.nodes.find((node) => node.code === code));
    return Math.max(0.1, Math.round(Math.hypot(p.x - q.x, p.y - q.y) * 10) / 10);
  }

  #changed() {
    this.render();
    this.dispatchEvent(new CustomEvent("change"));
  }

  // ------------------------------------------------------------ drawing

  /** Draw the graph again as it stands, keeping the pan and zoom. */
  render() {
    const routeEdges = new Set(this.route.slice(1).map((code, i) => edgeKey(this.route[i], code)));
    const codes = new Set(this.nodes.map((node) => node.code));
    const elements = [
      ...this.nodes.map((node) => this.#node(node)),
      ...this.edges.filter((edge) => codes.has(edge.a) && codes.has(edge.b)).map((edge) => this.#edge(edge, routeEdges)),
      ...this.nodes.flatMap((node) => this.#robotMarkers(node)),
    ];
    this.cy.batch(() => {
      this.cy.elements().remove();
      this.cy.add(elements);
    });
  }

  #node(node) {
    const classes = ["submap"];
    if (this.route.includes(node.code)) classes.push("route");
    if (this.linking === node.code) classes.push("linking");
    if ((this.robots.get(node.code) || []).length) classes.push("robot");
    return {
      group: "nodes", classes,
      data: { id: node.code, name: node.name || node.code },
      position: toModel(node),
    };
  }

  #edge(edge, routeEdges) {
    const key = edgeKey(edge.a, edge.b);
    const classes = [];
    if (routeEdges.has(key)) classes.push("route");
    if (this.invalid.has(key)) classes.push("invalid");
    if (this.selected === key) classes.push("selected");
    return { group: "edges", classes, data: { id: key, source: edge.a, target: edge.b, cost: formatCost(edge.cost) } };
  }

  /** A small dot per robot at the top right of its sub-map's node, named on hover. */
  #robotMarkers(node) {
    return (this.robots.get(node.code) || []).map((robot, index) => ({
      group: "nodes", classes: ["robot-marker"], grabbable: false,
      data: { id: `robot:${robot}`, robot, on: node.code, index },
      position: markerPosition(toModel(node), index),
    }));
  }

  #moveRobots(submap) {
    for (const marker of this.cy.nodes(`.robot-marker[on = "${submap.id()}"]`)) {
      marker.position(markerPosition(submap.position(), marker.data("index")));
    }
  }
}

function toModel(node) {
  return { x: node.x * UNITS_PER_M, y: -node.y * UNITS_PER_M };
}

function toMetres(position) {
  return { x: Math.round((position.x / UNITS_PER_M) * 100) / 100, y: Math.round((-position.y / UNITS_PER_M) * 100) / 100 };
}

function markerPosition(centre, index) {
  const offset = NODE_PX / 2 - 4;
  return { x: centre.x + offset + index * (ROBOT_PX - 2), y: centre.y - offset };
}

function formatCost(cost) {
  return Number.isInteger(cost) ? String(cost) : cost.toFixed(1);
}

const STYLE = [
  {
    selector: "node.submap",
    style: {
      width: NODE_PX, height: NODE_PX, "background-color": COLORS.surface, "border-color": COLORS.accent, "border-width": 2.5,
      // Its code's initials would hide its name: the name stands under the node.
      label: "data(name)", "text-valign": "bottom", "text-halign": "center", "text-margin-y": 3, "font-size": 10.5,
      color: COLORS.muted, "text-background-color": "#f7f8fb", "text-background-opacity": 0.8,
    },
  },
  { selector: "node.submap.route", style: { "background-color": COLORS.okSoft, "border-color": COLORS.ok } },
  { selector: "node.submap.linking", style: { "background-color": COLORS.accentSoft, "border-style": "dashed" } },
  { selector: "node.submap.robot", style: { "border-width": 4 } },
  {
    selector: "node.robot-marker",
    style: { width: ROBOT_PX, height: ROBOT_PX, "background-color": COLORS.warn, "border-color": "#fff", "border-width": 2, label: "", events: "no" },
  },
  {
    selector: "edge",
    style: {
      width: 3, "line-color": COLORS.edge, "curve-style": "straight", label: "data(cost)", "font-size": 11, color: COLORS.muted,
      "text-background-color": "#f7f8fb", "text-background-opacity": 1, "text-background-padding": 2, "overlay-padding": 6,
    },
  },
  { selector: "edge.selected", style: { width: 5, "line-color": COLORS.accent } },
  { selector: "edge.route", style: { width: 6, "line-color": COLORS.ok } },
  { selector: "edge.invalid", style: { "line-color": COLORS.danger, "line-style": "dashed", "line-dash-pattern": [8, 6] } },
];
