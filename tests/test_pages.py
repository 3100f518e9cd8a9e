"""The web UI's pages per persona, through Django's test client: who sees which page and
which controls. Browser behaviour is in ``test_browser_*.py``."""

from __future__ import annotations

import math

import pytest
from django.contrib.auth.models import User
from django.test import Client

from maps.models import Building, SubMap
from tests.conftest import make_robot, make_submap, make_tag

pytestmark = pytest.mark.django_db


def signed_in(user: User) -> Client:
    client = Client()
    client.force_login(user)
    return client


@pytest.fixture
def submap(building: Building) -> SubMap:
    return make_submap(building)


@pytest.fixture
def robot(building: Building) -> str:
    make_robot(name="r1", buildings=[building])
    return "r1"


def test_it_redirects_anonymous_visitors_to_the_sign_in_page(building: Building) -> None:
    answer = Client().get("/")
    assert answer.status_code == 302
    assert answer["Location"].startswith("/accounts/login/")


def test_the_sign_in_page_is_styled_like_the_app() -> None:
    page = Client().get("/accounts/login/").content.decode()
    assert "css/app.css" in page
    assert 'name="username"' in page
    assert 'name="password"' in page


def test_signing_in_opens_the_fleet_dashboard(operator: User) -> None:
    client = Client()
    answer = client.post("/accounts/login/", {"username": "operator", "password": "pw-operator"})
    assert answer.status_code == 302
    assert answer["Location"] == "/"
    assert 'id="fleet-table"' in client.get("/").content.decode()


def test_signing_out_takes_a_post(operator: User) -> None:
    client = signed_in(operator)
    assert client.post("/accounts/logout/").status_code == 302
    assert client.get("/").status_code == 302


def test_the_dashboard_loads_its_script_and_the_bundled_roslib_path(viewer: User) -> None:
    page = signed_in(viewer).get("/").content.decode()
    assert "js/fleet.js" in page
    assert "cdn" not in page.lower()
    assert "unpkg" not in page.lower()


def test_it_tells_someone_without_a_role_that_they_have_none(outsider: User) -> None:
    page = signed_in(outsider).get("/").content.decode()
    assert "no role yet" in page
    assert "js/fleet.js" not in page


@pytest.mark.parametrize("persona", ["admin", "operator"])
def test_people_who_drive_see_the_teleop_and_goal_controls(
    persona: str, robot: str, request: pytest.FixtureRequest
) -> None:
    page = signed_in(request.getfixturevalue(persona)).get(f"/robots/{robot}/").content.decode()
    for control in ('id="teleop-card"', 'id="stop-button"', 'id="goal-card"', 'data-tool="goal"'):
        assert control in page


def test_a_viewer_sees_the_robot_but_no_controls(viewer: User, robot: str) -> None:
    page = signed_in(viewer).get(f"/robots/{robot}/").content.decode()
    assert 'id="map-canvas"' in page
    assert 'id="camera-card"' in page
    for control in ("teleop-card", "stop-button", "goal-card", "map-tools", "lock-acquire"):
        assert control not in page


def test_the_robot_page_rejects_outsider(outsider: User, robot: str) -> None:
    assert signed_in(outsider).get(f"/robots/{robot}/").status_code == 404


def test_an_unknown_robot_is_not_found(operator: User, building: Building) -> None:
    assert signed_in(operator).get("/robots/ghost/").status_code == 404


def test_admins_get_the_topology_editor_and_upload(admin: User, submap: SubMap) -> None:
    page = signed_in(admin).get("/buildings/boccioni_1/").content.decode()
    assert 'id="topology-save"' in page
    assert 'id="upload-link"' in page


@pytest.mark.parametrize("persona", ["operator", "viewer"])
def test_operators_and_viewers_see_the_building_without_editors(
    persona: str, submap: SubMap, request: pytest.FixtureRequest
) -> None:
    page = (
        signed_in(request.getfixturevalue(persona)).get("/buildings/boccioni_1/").content.decode()
    )
    assert 'id="topology"' in page
    assert "CorridorA" in page
    assert 'id="topology-save"' not in page
    assert 'id="upload-link"' not in page


def test_the_building_page_rejects_outsider(outsider: User, building: Building) -> None:
    assert signed_in(outsider).get("/buildings/boccioni_1/").status_code == 404


def test_the_buildings_list_shows_only_member_buildings(operator: User, building: Building) -> None:
    Building.objects.create(code="elsewhere", name="Elsewhere")
    page = signed_in(operator).get("/buildings/").content.decode()
    assert "boccioni_1" in page
    assert "elsewhere" not in page


def test_only_admins_place_tags_on_a_submap(admin: User, operator: User, submap: SubMap) -> None:
    url = "/buildings/boccioni_1/maps/CorridorA/"
    assert 'id="place-tag"' in signed_in(admin).get(url).content.decode()
    assert 'id="place-tag"' not in signed_in(operator).get(url).content.decode()


def test_the_submap_page_rejects_outsider_and_unknown_maps(
    outsider: User, operator: User, submap: SubMap
) -> None:
    assert signed_in(outsider).get("/buildings/boccioni_1/maps/CorridorA/").status_code == 404
    assert signed_in(operator).get("/buildings/boccioni_1/maps/Nowhere/").status_code == 404


def test_only_admins_open_the_upload_page(admin: User, operator: User, building: Building) -> None:
    assert signed_in(admin).get("/buildings/boccioni_1/upload/").status_code == 200
    assert signed_in(operator).get("/buildings/boccioni_1/upload/").status_code == 403


def test_the_page_hands_its_script_the_role_and_subject(operator: User, robot: str) -> None:
    page = signed_in(operator).get(f"/robots/{robot}/").content.decode()
    assert '"role": "operator"' in page
    assert '"robot": "r1"' in page


def test_headings_are_shown_in_degrees_on_every_page(viewer: User, submap: SubMap) -> None:
    # Radians stay on the wire and in the API; people read degrees, as on the robot page.
    make_tag(submap, yaw=math.pi / 2)
    SubMap.objects.filter(pk=submap.pk).update(origin_yaw=-math.pi)
    client = signed_in(viewer)
    building_page = client.get("/buildings/boccioni_1/").content.decode()
    assert "1.00 m, 0.50 m, 90°" in building_page
    submap_page = client.get("/buildings/boccioni_1/maps/CorridorA/").content.decode()
    assert "-180°" in submap_page
    assert "-3.14" not in submap_page


def test_the_live_map_gives_goals_to_those_who_drive(
    operator: User, viewer: User, building: Building
) -> None:
    url = "/buildings/boccioni_1/map/"
    page = signed_in(operator).get(url).content.decode()
    assert 'id="floor-plan"' in page
    assert 'id="tool-goal"' in page
    assert "vendor/leaflet.css" in page
    assert 'id="tool-goal"' not in signed_in(viewer).get(url).content.decode()


def test_the_live_map_rejects_outsider(outsider: User, building: Building) -> None:
    assert signed_in(outsider).get("/buildings/boccioni_1/map/").status_code == 404


def test_a_missing_page_is_a_styled_404_with_the_way_back(
    operator: User, building: Building
) -> None:
    answer = signed_in(operator).get("/buildings/nowhere/")
    assert answer.status_code == 404
    page = answer.content.decode()
    assert 'data-status="404"' in page
    assert "Back to the fleet" in page
    assert "app.css" in page


def test_a_forbidden_page_is_a_styled_403(operator: User, building: Building) -> None:
    answer = signed_in(operator).get("/buildings/boccioni_1/upload/")
    assert answer.status_code == 403
    assert 'data-status="403"' in answer.content.decode()


def test_strangers_get_a_styled_404_that_offers_to_sign_in(db: None) -> None:
    answer = Client().get("/no/such/page/")
    assert answer.status_code == 404
    assert "Sign in" in answer.content.decode()
