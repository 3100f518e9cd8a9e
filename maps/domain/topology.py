"""A building's topology graph: validation, routing across sub-maps and tag coverage.

Nodes are sub-map codes; edges are undirected crossings with a positive cost; a tag
standing in sub-map ``submap`` and linking to ``links_to`` is what lets a robot cross
that edge in that direction, so routes follow an edge only the ways a tag leads: a robot
sent along an edge with no tag would drive to nothing and give up. The robot agent runs
the same ``route_between`` on the topology it downloads (whose ``crossings`` list every
tag of the building), so the server and the robot agree on every route. A robot crosses
at a tag by standing at its ``approach_pose``, reading its QR code.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from itertools import pairwise

import networkx as nx

from cloudnav_core.se2 import Pose, ahead, wrap
from maps.exceptions import NoRouteError, TopologyError

APPROACH = 0.5
"""Metres in front of a tag where a robot crossing there stands to read its QR code."""


@dataclass(frozen=True)
class Edge:
    a: str
    b: str
    cost: float

    def key(self) -> frozenset[str]:
        return frozenset((self.a, self.b))


@dataclass(frozen=True)
class TagLink:
    marker_id: int
    submap: str
    links_to: str


@dataclass(frozen=True)
class RouteStep:
    """One sub-map of a route; ``tag`` is the tag to drive to in it (None at the goal)."""

    submap: str
    tag: TagLink | None


def validate_graph(nodes: Iterable[str], edges: Sequence[Edge]) -> None:
    """Raise TopologyError unless each edge joins two known sub-maps, once, at a positive cost."""
    known = set(nodes)
    seen: set[frozenset[str]] = set()
    for index, edge in enumerate(edges):
        field = f"edges[{index}]"
        if edge.a not in known or edge.b not in known:
            missing = edge.a if edge.a not in known else edge.b
            raise TopologyError(field, f"'{missing}' is not a sub-map of this building.")
        if edge.a == edge.b:
            raise TopologyError(field, "An edge cannot join a sub-map to itself.")
        if not math.isfinite(edge.cost) or edge.cost <= 0:
            raise TopologyError(field, "The cost must be a positive number.")
        if edge.key() in seen:
            raise TopologyError(field, f"{edge.a} and {edge.b} are already joined.")
        seen.add(edge.key())


def topology_graph(nodes: Iterable[str], edges: Sequence[Edge]) -> nx.Graph:
    """Build the graph in sorted order, so equal-cost routes break ties the same way everywhere."""
    graph = nx.Graph()
    graph.add_nodes_from(sorted(nodes))
    for edge in sorted(edges, key=lambda e: (min(e.a, e.b), max(e.a, e.b))):
        graph.add_edge(edge.a, edge.b, cost=edge.cost)
    return graph


def crossable_graph(
    nodes: Iterable[str], edges: Sequence[Edge], leading: Mapping[tuple[str, str], TagLink]
) -> nx.DiGraph:
    """The directed graph of the crossings a robot can make: each edge, each way a tag
    leads along it (``leading``: see ``_tags_by_direction``), at the edge's cost."""
    graph = nx.DiGraph()
    graph.add_nodes_from(sorted(nodes))
    for edge in sorted(edges, key=lambda e: (min(e.a, e.b), max(e.a, e.b))):
        for here, there in ((edge.a, edge.b), (edge.b, edge.a)):
            if (here, there) in leading:
                graph.add_edge(here, there, cost=edge.cost)
    return graph


def route_between(
    nodes: Iterable[str],
    edges: Sequence[Edge],
    tags: Iterable[TagLink],
    start: str,
    goal: str,
) -> list[RouteStep]:
    """Return the cheapest sub-map sequence from ``start`` to ``goal`` that crosses each
    border where a tag leads, with that tag for every step but the last.

    Raises TopologyError ("from"/"to") for an unknown sub-map, NoRouteError when no such
    sequence exists (naming the border with no tag when edges alone would join them).
    """
    nodes = list(nodes)
    leading = _tags_by_direction(tags)
    graph = crossable_graph(nodes, edges, leading)
    for field, code in (("from", start), ("to", goal)):
        if code not in graph:
            raise TopologyError(field, f"'{code}' is not a sub-map of this building.")
    try:
        path = nx.shortest_path(graph, start, goal, weight="cost")
    except nx.NetworkXNoPath:
        raise NoRouteError("to", _no_route(nodes, edges, leading, start, goal)) from None
    steps = [RouteStep(here, leading[(here, there)]) for here, there in pairwise(path)]
    return [*steps, RouteStep(goal, None)]


def _no_route(
    nodes: list[str],
    edges: Sequence[Edge],
    leading: Mapping[tuple[str, str], TagLink],
    start: str,
    goal: str,
) -> str:
    """Why no route joins ``start`` to ``goal``: the first border without a tag on the
    cheapest way the edges alone offer, or no way at all."""
    try:
        path = nx.shortest_path(topology_graph(nodes, edges), start, goal, weight="cost")
    except nx.NetworkXNoPath:
        return f"No route joins {start} and {goal}."
    here, there = next(step for step in pairwise(path) if step not in leading)
    return f"No route joins {start} and {goal}: no tag lets a robot cross from {here} to {there}."


def _tags_by_direction(tags: Iterable[TagLink]) -> dict[tuple[str, str], TagLink]:
    """Map (sub-map, linked sub-map) to its tag; the lowest marker id wins when several stand."""
    found: dict[tuple[str, str], TagLink] = {}
    for tag in sorted(tags, key=lambda t: t.marker_id):
        found.setdefault((tag.submap, tag.links_to), tag)
    return found


@dataclass(frozen=True)
class Coverage:
    """What the tags leave uncovered: edges no tag lets a robot cross, and tags with no edge."""

    uncrossable: list[tuple[str, str]]
    dangling: list[TagLink]


def tag_coverage(edges: Sequence[Edge], tags: Sequence[TagLink]) -> Coverage:
    """List each edge direction that has no tag, and each tag linking along no edge.

    A tag linking a sub-map to itself (an entrance tag) needs no edge.
    """
    directions = _tags_by_direction(tags)
    uncrossable = [
        (here, there)
        for edge in edges
        for here, there in ((edge.a, edge.b), (edge.b, edge.a))
        if (here, there) not in directions
    ]
    joined = {edge.key() for edge in edges}
    dangling = [
        tag
        for tag in tags
        if tag.submap != tag.links_to and frozenset((tag.submap, tag.links_to)) not in joined
    ]
    return Coverage(uncrossable, dangling)


def approach_pose(tag: Pose) -> Pose:
    """``APPROACH`` metres in front of a tag at ``tag`` (yaw = its outward normal),
    facing it: where a robot stands to read it."""
    return (*ahead(tag, APPROACH), wrap(tag[2] + math.pi))
