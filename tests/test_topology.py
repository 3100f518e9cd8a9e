"""The topology domain: graph validation, routes across sub-maps, and tag coverage."""

from __future__ import annotations

import pytest

from maps.domain.topology import Edge, TagLink, route_between, tag_coverage, validate_graph
from maps.exceptions import NoRouteError, TopologyError

NODES = ["A", "B", "C", "D"]
CHAIN = [Edge("A", "B", 1.0), Edge("B", "C", 1.0), Edge("C", "D", 1.0)]
TAGS = [TagLink(1, "A", "B"), TagLink(2, "B", "A"), TagLink(3, "B", "C"), TagLink(4, "C", "D")]


def test_it_accepts_a_simple_chain() -> None:
    validate_graph(NODES, CHAIN)


@pytest.mark.parametrize(
    ("edge", "message"),
    [
        (Edge("A", "Z", 1.0), "'Z' is not a sub-map"),
        (Edge("A", "A", 1.0), "itself"),
        (Edge("A", "C", 0.0), "positive"),
        (Edge("A", "C", -2.0), "positive"),
        (Edge("A", "C", float("nan")), "positive"),
        (Edge("B", "A", 3.0), "already joined"),
    ],
)
def test_it_refuses_a_bad_edge_naming_its_index(edge: Edge, message: str) -> None:
    with pytest.raises(TopologyError, match=message) as caught:
        validate_graph(NODES, [*CHAIN, edge])
    assert caught.value.field == "edges[3]"


def test_it_routes_by_cost_not_by_hops() -> None:
    edges = [*CHAIN, Edge("A", "D", 10.0)]
    steps = route_between(NODES, edges, TAGS, "A", "D")
    assert [s.submap for s in steps] == ["A", "B", "C", "D"]


def test_it_names_the_tag_leading_on_from_each_step() -> None:
    steps = route_between(NODES, CHAIN, TAGS, "A", "D")
    assert [s.tag.marker_id if s.tag else None for s in steps] == [1, 3, 4, None]


def test_a_route_never_crosses_a_border_no_tag_leads_across() -> None:
    # D -> C and C -> B have no tag: a robot sent that way would find nothing to drive to.
    with pytest.raises(NoRouteError, match="no tag lets a robot cross from D to C"):
        route_between(NODES, CHAIN, TAGS, "D", "A")


def test_a_route_takes_a_dearer_border_a_tag_leads_across_over_a_cheap_one_without() -> None:
    edges = [*CHAIN, Edge("A", "D", 10.0)]
    tags = [*TAGS, TagLink(5, "D", "A")]
    steps = route_between(NODES, edges, tags, "D", "A")
    assert [(s.submap, s.tag.marker_id if s.tag else None) for s in steps] == [
        ("D", 5),
        ("A", None),
    ]


def test_a_route_to_itself_is_one_step() -> None:
    assert [s.submap for s in route_between(NODES, CHAIN, TAGS, "B", "B")] == ["B"]


def test_equal_cost_routes_are_chosen_the_same_whatever_the_edge_order() -> None:
    square = [Edge("A", "B", 1), Edge("B", "D", 1), Edge("A", "C", 1), Edge("C", "D", 1)]
    tags = [TagLink(i, e.a, e.b) for i, e in enumerate(square)]
    first = route_between(NODES, square, tags, "A", "D")
    second = route_between(reversed(NODES), list(reversed(square)), tags[::-1], "A", "D")
    assert first == second


@pytest.mark.parametrize(("start", "goal", "field"), [("Z", "A", "from"), ("A", "Z", "to")])
def test_it_refuses_an_unknown_end(start: str, goal: str, field: str) -> None:
    with pytest.raises(TopologyError) as caught:
        route_between(NODES, CHAIN, TAGS, start, goal)
    assert caught.value.field == field


def test_it_reports_no_route_between_disconnected_sub_maps() -> None:
    with pytest.raises(NoRouteError, match=r"No route joins A and E\.$"):
        route_between([*NODES, "E"], CHAIN, TAGS, "A", "E")


def test_coverage_lists_each_edge_direction_without_a_tag() -> None:
    coverage = tag_coverage(CHAIN, TAGS)
    assert sorted(coverage.uncrossable) == [("C", "B"), ("D", "C")]


def test_coverage_lists_tags_linking_along_no_edge() -> None:
    stray = TagLink(9, "A", "D")
    assert tag_coverage(CHAIN, [*TAGS, stray]).dangling == [stray]


def test_an_entrance_tag_linking_to_its_own_sub_map_needs_no_edge() -> None:
    assert tag_coverage(CHAIN, [*TAGS, TagLink(0, "A", "A")]).dangling == []
