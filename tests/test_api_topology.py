"""Topology read and replace, route answers, and tag coverage validation over the API."""

from __future__ import annotations

from typing import Any

import pytest
from django.contrib.auth.models import User

from maps.models import Building, TopologyEdge
from tests.conftest import client_for, make_submap, make_tag

B = "/api/buildings/boccioni_1"


@pytest.fixture
def chain(building: Building) -> Building:
    maps = {code: make_submap(building, code=code) for code in ("A", "B", "C")}
    make_tag(maps["A"], marker_id=1, links_to=maps["B"])
    make_tag(maps["B"], marker_id=2, links_to=maps["C"])
    make_tag(maps["B"], marker_id=3, links_to=maps["A"])
    return building


def put(user: User, document: object) -> Any:
    return client_for(user).put(f"{B}/topology", document, format="json")


def test_it_replaces_the_graph_and_node_positions(chain: Building, admin: User) -> None:
    document = {
        "nodes": [{"code": "A", "x": 1, "y": 2}],
        "edges": [{"a": "A", "b": "B", "cost": 2}, {"a": "B", "b": "C", "cost": 3}],
    }
    response = put(admin, document)
    assert response.status_code == 200, response.json()
    body = client_for(admin).get(f"{B}/topology").json()
    assert body["edges"] == [{"a": "A", "b": "B", "cost": 2.0}, {"a": "B", "b": "C", "cost": 3.0}]
    assert body["nodes"][0] == {"code": "A", "name": "", "x": 1.0, "y": 2.0}


@pytest.mark.parametrize(
    "edges",
    [
        [{"a": "A", "b": "Z", "cost": 1}],
        [{"a": "A", "b": "A", "cost": 1}],
        [{"a": "A", "b": "B", "cost": 0}],
        [{"a": "A", "b": "B", "cost": 1}, {"a": "B", "b": "A", "cost": 2}],
        [{"a": "A", "b": "B"}],
    ],
)
def test_it_refuses_an_invalid_graph_whole(
    chain: Building, admin: User, edges: list[dict[str, object]]
) -> None:
    put(admin, {"edges": [{"a": "B", "b": "C", "cost": 1}]})
    response = put(admin, {"edges": edges})
    assert response.status_code == 400
    assert "edges" in str(response.json())
    assert list(TopologyEdge.objects.values_list("cost", flat=True)) == [1.0]


def test_the_route_names_each_sub_map_and_the_tag_to_drive_to(
    chain: Building, viewer: User, admin: User
) -> None:
    put(admin, {"edges": [{"a": "A", "b": "B", "cost": 1}, {"a": "B", "b": "C", "cost": 1}]})
    response = client_for(viewer).get(f"{B}/route", {"from": "A", "to": "C"})
    steps = response.json()["steps"]
    assert [s["map"] for s in steps] == ["A", "B", "C"]
    assert [s["tag"] and s["tag"]["marker_id"] for s in steps] == [1, 2, None]
    assert steps[0]["tag"]["links_to"] == "B"


def test_the_route_follows_the_costs(chain: Building, viewer: User, admin: User) -> None:
    edges = [
        {"a": "A", "b": "B", "cost": 1},
        {"a": "B", "b": "C", "cost": 1},
        {"a": "A", "b": "C", "cost": 5},
    ]
    put(admin, {"edges": edges})
    steps = client_for(viewer).get(f"{B}/route", {"from": "A", "to": "C"}).json()["steps"]
    assert [s["map"] for s in steps] == ["A", "B", "C"]


def test_the_route_never_uses_an_edge_no_tag_lets_a_robot_cross(
    chain: Building, viewer: User, admin: User
) -> None:
    # A -> C is cheap, but no tag in A leads to C: robots go round by B.
    edges = [
        {"a": "A", "b": "B", "cost": 1},
        {"a": "B", "b": "C", "cost": 1},
        {"a": "A", "b": "C", "cost": 0.5},
    ]
    assert put(admin, {"edges": edges}).status_code == 200
    steps = client_for(viewer).get(f"{B}/route", {"from": "A", "to": "C"}).json()["steps"]
    assert [s["map"] for s in steps] == ["A", "B", "C"]
    back = client_for(viewer).get(f"{B}/route", {"from": "C", "to": "A"})
    assert back.status_code == 404
    assert "no tag lets a robot cross from C to A" in str(back.json())


def test_the_topology_lists_the_crossings_its_tags_allow(chain: Building, viewer: User) -> None:
    body = client_for(viewer).get(f"{B}/topology").json()
    assert body["crossings"] == [
        {"from": "A", "to": "B", "marker_id": 1},
        {"from": "B", "to": "C", "marker_id": 2},
        {"from": "B", "to": "A", "marker_id": 3},
    ]


def test_an_editor_asks_what_a_graph_would_leave_uncrossable_before_saving_it(
    chain: Building, admin: User
) -> None:
    proposal = {"edges": [{"a": "A", "b": "B", "cost": 1}, {"a": "A", "b": "C", "cost": 1}]}
    response = client_for(admin).post(f"{B}/topology/validation", proposal, format="json")
    assert response.status_code == 200
    assert response.json()["uncrossable_edges"] == [
        {"from": "A", "to": "C"},
        {"from": "C", "to": "A"},
    ]
    assert not TopologyEdge.objects.exists()  # nothing was saved
    bad = client_for(admin).post(
        f"{B}/topology/validation", {"edges": [{"a": "A", "b": "Z", "cost": 1}]}, format="json"
    )
    assert bad.status_code == 400
    assert "edges" in str(bad.json())


def test_a_route_to_an_unreachable_sub_map_is_404(chain: Building, viewer: User) -> None:
    response = client_for(viewer).get(f"{B}/route", {"from": "A", "to": "C"})
    assert response.status_code == 404
    assert "to" in response.json()


@pytest.mark.parametrize(
    ("query", "field"), [({"to": "C"}, "from"), ({"from": "A", "to": "Q"}, "to")]
)
def test_a_bad_route_request_is_400_naming_the_parameter(
    chain: Building, viewer: User, query: dict[str, str], field: str
) -> None:
    response = client_for(viewer).get(f"{B}/route", query)
    assert response.status_code == 400
    assert field in response.json()


def test_validation_lists_uncrossable_edges_and_dangling_tags(chain: Building, admin: User) -> None:
    put(admin, {"edges": [{"a": "A", "b": "B", "cost": 1}, {"a": "A", "b": "C", "cost": 1}]})
    report = client_for(admin).get(f"{B}/topology/validation").json()
    assert report["valid"] is False
    assert sorted((e["from"], e["to"]) for e in report["uncrossable_edges"]) == [
        ("A", "C"),
        ("C", "A"),
    ]
    assert report["dangling_tags"] == [{"marker_id": 2, "map": "B", "links_to": "C"}]
