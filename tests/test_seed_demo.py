"""The demo building: the paper's scenario, seeded idempotently."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from django.contrib.auth import authenticate
from django.contrib.auth.models import User
from django.core.management import call_command

from maps import services
from maps.domain import demo_building
from maps.models import Building, EnvironmentalTag, ParkingSpot, SubMap, TopologyEdge
from tests.conftest import client_for

PAPER_ROUTE = list(demo_building.PAPER_ROUTE)
SEEDED = (SubMap, EnvironmentalTag, TopologyEdge, ParkingSpot)


@pytest.fixture
def seeded(db: None, tmp_path: Path) -> Path:
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--tokens-file", str(tokens), stdout=io.StringIO())
    return tokens


def test_it_creates_the_papers_sub_maps(seeded: Path) -> None:
    codes = set(SubMap.objects.values_list("code", flat=True))
    assert codes == {*PAPER_ROUTE, "RoomA", "RoomB"}


def test_the_route_from_corridor_a_to_office_7_is_the_papers(seeded: Path) -> None:
    token = next(iter(json.loads(seeded.read_text()).values()))
    steps = (
        client_for(token)
        .get("/api/buildings/boccioni_1/route", {"from": "CorridorA", "to": "Office7"})
        .json()["steps"]
    )
    assert [s["map"] for s in steps] == PAPER_ROUTE
    assert all(s["tag"] for s in steps[:-1])


def test_every_edge_can_be_crossed_both_ways(seeded: Path) -> None:
    token = next(iter(json.loads(seeded.read_text()).values()))
    report = client_for(token).get("/api/buildings/boccioni_1/topology/validation").json()
    assert report == {"valid": True, "uncrossable_edges": [], "dangling_tags": []}


def test_there_is_an_entrance_tag_at_corridor_a(seeded: Path) -> None:
    assert EnvironmentalTag.objects.filter(
        submap__code="CorridorA", links_to__code="CorridorA"
    ).exists()


def test_running_it_again_changes_nothing(seeded: Path) -> None:
    before = [list(m.objects.order_by("pk").values()) for m in SEEDED]
    tokens = seeded.read_text()
    call_command("seed_demo", "--tokens-file", str(seeded), stdout=io.StringIO())
    after = [list(m.objects.order_by("pk").values()) for m in SEEDED]
    assert before == after
    assert seeded.read_text() == tokens


def test_the_demo_users_sign_in_with_the_printed_passwords(db: None, tmp_path: Path) -> None:
    out = io.StringIO()
    call_command("seed_demo", "--tokens-file", str(tmp_path / "t.json"), stdout=out)
    for line in out.getvalue().splitlines():
        if line.strip().startswith("user "):
            _, name, _, password = line.split()
            assert authenticate(username=name, password=password) is not None
    assert Building.objects.get().members.count() == 3


def test_the_printed_robot_tokens_get_maps(seeded: Path) -> None:
    for token in json.loads(seeded.read_text()).values():
        assert (
            client_for(token).get("/api/buildings/boccioni_1/maps/Office7/bundle").status_code
            == 200
        )


def test_seeding_again_keeps_what_people_changed(seeded: Path) -> None:
    admin = User.objects.get(username="admin")
    admin.set_password("a-secret-of-my-own")
    admin.save()
    moved = EnvironmentalTag.objects.order_by("marker_id").first()
    assert moved is not None
    EnvironmentalTag.objects.filter(pk=moved.pk).update(x=moved.x + 1.0, yaw=moved.yaw + 0.5)
    placed = EnvironmentalTag.objects.create(
        building=moved.building,
        submap=moved.submap,
        links_to=moved.links_to,
        marker_id=499,
        x=1.0,
        y=1.0,
        yaw=0.0,
    )
    TopologyEdge.objects.filter(pk=TopologyEdge.objects.order_by("pk")[0].pk).update(cost=42)
    SubMap.objects.filter(code="RoomA").update(node_x=-7.0, name="Room A, renamed")
    ParkingSpot.objects.filter(name="P-Atrium1-SW").update(x=19.5, name="my own corner")
    before = [list(m.objects.order_by("pk").values()) for m in SEEDED]

    call_command("seed_demo", "--tokens-file", str(seeded), stdout=io.StringIO())

    after = [list(m.objects.order_by("pk").values()) for m in SEEDED]
    assert after == before
    assert EnvironmentalTag.objects.filter(pk=placed.pk).exists()
    assert authenticate(username="admin", password="a-secret-of-my-own") is not None
    assert authenticate(username="admin", password="admin-demo") is None


def test_seeding_again_creates_what_is_missing(seeded: Path) -> None:
    EnvironmentalTag.objects.order_by("marker_id")[0].delete()
    User.objects.filter(username="viewer").delete()
    call_command("seed_demo", "--tokens-file", str(seeded), stdout=io.StringIO())
    assert EnvironmentalTag.objects.count() == len(demo_building.demo_building("x").tags)
    assert authenticate(username="viewer", password="viewer-demo") is not None


def test_it_seeds_a_parking_spot_for_every_demo_robot_where_a_robot_can_stand(
    seeded: Path,
) -> None:
    spots = list(ParkingSpot.objects.select_related("submap"))
    assert len(spots) == len(demo_building.demo_building("x").parking)
    assert len(spots) >= len(json.loads(seeded.read_text()))
    for spot in spots:
        services.goal_check_of(spot.submap).check((spot.x, spot.y), tolerance=0.0)


def test_seeding_again_never_puts_a_demo_spot_over_one_people_made(seeded: Path) -> None:
    demo = ParkingSpot.objects.get(name="P-Atrium3-SW")
    mine = {"building": demo.building, "submap": demo.submap, "yaw": 0.0}
    demo.delete()
    ParkingSpot.objects.create(name="by the sofa", x=demo.x + 0.5, y=demo.y, **mine)
    ParkingSpot.objects.get(name="P-RoomB-SW").delete()
    ParkingSpot.objects.create(name="P-RoomB-SW", x=28.0, y=9.3, **mine)  # its name, in Atrium 3

    call_command("seed_demo", "--tokens-file", str(seeded), stdout=io.StringIO())

    assert not ParkingSpot.objects.filter(name="P-Atrium3-SW").exists()
    assert ParkingSpot.objects.get(name="by the sofa").x == demo.x + 0.5
    assert ParkingSpot.objects.get(name="P-RoomB-SW").submap == demo.submap
    assert ParkingSpot.objects.count() == len(demo_building.demo_building("x").parking)
