// A building's topology graph on SVG: sub-maps as nodes at their (x, y) in metres, edges
// with their costs, a route and robots highlighted. When editable: drag nodes, click two
// nodes to join them, click an edge to select it (then set its cost or remove it).

const SVG = "http://www.w3.org/2000/svg";
const NODE_RADIUS = 19;
const PADDING = 44;

function svg(tag, attributes = {}, text = null) {
  const node = document.createElementNS(SVG, tag);
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  if (text !== null) node.textContent = text;
  return node;
}

export function edgeKey(a, b) {
  return [a, b].sort().join("\u2194");
}

export class TopologyView extends EventTarget {
  constructor(element, { editable = false } = {}) {
    super();
    this.svg = element;
    this.editable = editable;
    this.nodes = [];
    this.edges = [];
    this.route = [];
    this.robots = new Map();
    this.invalid = new Set();
    this.selected = null;
    this.linking = null;
    this.frame = null;
    element.classList.toggle("editable", editable);
    new ResizeObserver(() => this.render()).observe(element);
  }

  load({ nodes, edges }) {
    this.nodes = nodes.map((node) => ({ ...node }));
    this.edges = edges.map((edge) => ({ ...edge }));
    this.selected = null;
    this.linking = null;
    this.frame = null;
    this.render();
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

  #clickNode(code) {
    if (!this.editable) return;
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

  // ------------------------------------------------------------ layout

  /** Fit the nodes' metres to the element once per load, so dragging keeps the scale. */
  #fit() {
    if (this.frame) return this.frame;
    const width = this.svg.clientWidth || 600;
    const height = this.svg.clientHeight || 400;
    const xs = this.nodes.map((n) => n.x);
    const ys = this.nodes.map((n) => n.y);
    const [minX, maxX, minY, maxY] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
    const scale = Math.min((width - 2 * PADDING) / (maxX - minX || 1), (height - 2 * PADDING) / (maxY - minY || 1));
    this.frame = { width, height, scale, cx: (minX + maxX) / 2, cy: (minY + maxY) / 2 };
    return this.frame;
  }

  #toScreen(node) {
    const f = this.#fit();
    return [f.width / 2 + (node.x - f.cx) * f.scale, f.height / 2 - (node.y - f.cy) * f.scale];
  }

  #toWorld(sx, sy) {
    const f = this.#fit();
    return [f.cx + (sx - f.width / 2) / f.scale, f.cy - (sy - f.height / 2) / f.scale];
  }

  // ------------------------------------------------------------ drawing

  render() {
    if (!this.nodes.length) {
      this.svg.replaceChildren();
      return;
    }
    const f = this.#fit();
    this.svg.setAttribute("viewBox", `0 0 ${f.width} ${f.height}`);
    const routeEdges = new Set(this.route.slice(1).map((code, i) => edgeKey(this.route[i], code)));
    const edges = this.edges.map((edge) => this.#edge(edge, routeEdges));
    const nodes = this.nodes.map((node) => this.#node(node));
    this.svg.replaceChildren(...edges, ...nodes);
  }

  #edge(edge, routeEdges) {
    const key = edgeKey(edge.a, edge.b);
    const [a, b] = [edge.a, edge.b].map((code) => this.nodes.find((node) => node.code === code));
    const group = svg("g", { class: "topo-edge-group", "data-edge": key });
    if (!a || !b) return group;
    const [x1, y1] = this.#toScreen(a);
    const [x2, y2] = this.#toScreen(b);
    const classes = ["topo-edge"];
    if (routeEdges.has(key)) classes.push("route");
    if (this.invalid.has(key)) classes.push("invalid");
    if (this.selected === key) classes.push("selected");
    group.append(
      svg("line", { x1, y1, x2, y2, class: classes.join(" ") }),
      svg("line", { x1, y1, x2, y2, class: "topo-edge-hit" }),
      svg("text", { x: (x1 + x2) / 2, y: (y1 + y2) / 2 - 6, class: "topo-cost", "text-anchor": "middle" }, formatCost(edge.cost)),
    );
    group.addEventListener("click", () => {
      if (!this.editable) return;
      this.selected = this.selected === key ? null : key;
      this.render();
      this.dispatchEvent(new CustomEvent("select"));
    });
    return group;
  }

  #node(node) {
    const [x, y] = this.#toScreen(node);
    const classes = ["topo-node"];
    if (this.route.includes(node.code)) classes.push("route");
    if (this.linking === node.code) classes.push("linking");
    const robots = this.robots.get(node.code) || [];
    if (robots.length) classes.push("robot");
    const group = svg("g", { class: classes.join(" "), "data-node": node.code, transform: `translate(${x} ${y})` });
    group.append(
      svg("circle", { r: NODE_RADIUS }),
      svg("text", { y: 4 }, shortCode(node.code)),
      svg("text", { y: NODE_RADIUS + 14, class: "sub" }, node.name || node.code),
    );
    robots.forEach((robot, index) => {
      const marker = svg("circle", { r: 7, cx: NODE_RADIUS - 4 + index * 10, cy: -NODE_RADIUS + 4, class: "topo-robot" });
      marker.append(svg("title", {}, robot));
      group.append(marker);
    });
    if (this.editable) this.#draggable(group, node);
    return group;
  }

  #draggable(group, node) {
    // Rendering replaces the node's element, so the drag listens on the window.
    group.addEventListener("pointerdown", (event) => {
      event.preventDefault();
      const start = { x: event.clientX, y: event.clientY, moved: false };
      const move = (e) => {
        if (Math.hypot(e.clientX - start.x, e.clientY - start.y) > 3) start.moved = true;
        if (!start.moved) return;
        const rect = this.svg.getBoundingClientRect();
        const f = this.#fit();
        const sx = ((e.clientX - rect.left) / rect.width) * f.width;
        const sy = ((e.clientY - rect.top) / rect.height) * f.height;
        const [wx, wy] = this.#toWorld(sx, sy);
        node.x = Math.round(wx * 100) / 100;
        node.y = Math.round(wy * 100) / 100;
        this.render();
      };
      const up = () => {
        window.removeEventListener("pointermove", move);
        window.removeEventListener("pointerup", up);
        if (start.moved) this.#changed();
        else this.#clickNode(node.code);
      };
      window.addEventListener("pointermove", move);
      window.addEventListener("pointerup", up);
    });
  }
}

function formatCost(cost) {
  return Number.isInteger(cost) ? String(cost) : cost.toFixed(1);
}

/** A node's label inside its circle: capitals and digits of a code such as CorridorA -> CA. */
function shortCode(code) {
  const initials = code.replace(/[^A-Z0-9]/g, "");
  return (initials.length >= 2 ? initials : code).slice(0, 4);
}
