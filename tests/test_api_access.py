"""Every map store and registry endpoint, asked by every persona.

Expected answers: members read their buildings; only admins write; an outsider is told
nothing exists (404) or gets an empty list; a robot reads its own buildings and gets 403
for others; no credential or a bad token gets 401.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest
from django.contrib.auth.models import User

from maps import services
from maps.domain.topology import Edge
from tests.conftest import (
    client_for,
    make_building,
    make_robot,
    make_submap,
    make_tag,
    make_user,
    map_pgm,
    map_yaml,
)

PERSONAS = [
    "admin",
    "operator",
    "viewer",
    "outsider",
    "robot",
    "foreign_robot",
    "bad_token",
    "anonymous",
]


@dataclass
class World:
    principals: dict[str, Any]
    tag_id: int


@pytest.fixture
def world(building: Any, admin: User, operator: User, viewer: User, outsider: User) -> World:
    corridor = make_submap(building, code="CorridorA")
    atrium = make_submap(building, code="Atrium1")
    tag = make_tag(corridor, links_to=atrium)
    make_tag(atrium, links_to=corridor)
    services.replace_topology(building, {}, [Edge("CorridorA", "Atrium1", 1.0)])
    other = make_building(code="other_1", members=[make_user("other_admin", "admin")])
    _, token = make_robot(name="r1", buildings=[building])
    _, foreign = make_robot(name="r2", buildings=[other])
    principals = {
        "admin": admin,
        "operator": operator,
        "viewer": viewer,
        "outsider": outsider,
        "robot": token,
        "foreign_robot": foreign,
        "bad_token": "cnr_not-a-token",
        "anonymous": None,
    }
    return World(principals, tag.pk)


def upload() -> dict[str, Any]:
    from django.core.files.uploadedfile import SimpleUploadedFile

    return {
        "code": "CorridorB",
        "image": SimpleUploadedFile("map.pgm", map_pgm()),
        "yaml": SimpleUploadedFile("map.yaml", map_yaml()),
    }


B = "/api/buildings/boccioni_1"
M = f"{B}/maps/CorridorA"
TOPOLOGY = {"edges": [{"a": "CorridorA", "b": "Atrium1", "cost": 2.0}]}
NEW_TAG = {
    "building": "boccioni_1",
    "submap": "Atrium1",
    "marker_id": 40,
    "x": 1,
    "y": 1,
    "yaw": 0,
    "links_to": "CorridorA",
}

READ = {
    "admin": 200,
    "operator": 200,
    "viewer": 200,
    "outsider": 404,
    "robot": 200,
    "foreign_robot": 403,
    "bad_token": 401,
    "anonymous": 401,
}
WRITE = {**READ, "operator": 403, "viewer": 403, "robot": 403}
ADMIN_ONLY = {**WRITE, "outsider": 403}
LIST = {**READ, "outsider": 200, "foreign_robot": 200}

# (method, path, body, expected statuses; "tag" in a path stands for the tag's id)
CASES: list[tuple[str, str, Any, dict[str, int]]] = [
    ("get", "/api/buildings/", None, LIST),
    ("post", "/api/buildings/", {"code": "new_1", "name": "New"}, {**ADMIN_ONLY, "admin": 201}),
    ("get", f"{B}/", None, READ),
    ("patch", f"{B}/", {"name": "Renamed"}, WRITE),
    ("delete", f"{B}/", None, {**WRITE, "admin": 204}),
    ("get", f"{B}/maps/", None, READ),
    ("post", f"{B}/maps/", "upload", {**WRITE, "admin": 201}),
    ("get", f"{M}/", None, READ),
    ("patch", f"{M}/", {"resolution": 0.1}, WRITE),
    ("delete", f"{M}/", None, {**WRITE, "admin": 204}),
    ("get", f"{M}/image", None, READ),
    ("get", f"{M}/grid", None, READ),
    ("get", f"{M}/export", None, READ),
    ("get", f"{M}/bundle", None, READ),
    ("get", f"{B}/topology", None, READ),
    ("put", f"{B}/topology", TOPOLOGY, WRITE),
    ("get", f"{B}/topology/validation", None, READ),
    ("post", f"{B}/topology/validation", TOPOLOGY, WRITE),
    ("get", f"{B}/route?from=CorridorA&to=Atrium1", None, READ),
    ("get", f"{B}/tags/print.pdf", None, READ),
    ("get", "/api/tags/", None, LIST),
    ("post", "/api/tags/", NEW_TAG, {**WRITE, "admin": 201}),
    ("get", "/api/tags/tag/", None, READ),
    ("patch", "/api/tags/tag/", {"x": 2.0}, WRITE),
    ("delete", "/api/tags/tag/", None, {**WRITE, "admin": 204}),
    ("get", "/api/tags/tag/print.png", None, READ),
    ("get", "/api/tags/tag/print.pdf", None, READ),
    ("get", "/api/robots/", None, {**ADMIN_ONLY, "foreign_robot": 403}),
    (
        "post",
        "/api/robots/",
        {"name": "r9", "buildings": ["boccioni_1"]},
        {**ADMIN_ONLY, "admin": 201},
    ),
    ("get", "/api/robots/r1/", None, ADMIN_ONLY),
    ("post", "/api/robots/r1/rotate_token", None, ADMIN_ONLY),
]


@pytest.mark.parametrize("persona", PERSONAS)
@pytest.mark.parametrize(
    ("method", "path", "body", "expected"), CASES, ids=lambda v: v if isinstance(v, str) else ""
)
def test_each_persona_gets_its_answer(
    world: World, persona: str, method: str, path: str, body: Any, expected: dict[str, int]
) -> None:
    client = client_for(world.principals[persona])
    path = path.replace("/tag/", f"/{world.tag_id}/")
    if body == "upload":
        response = client.post(path, upload(), format="multipart")
    else:
        response = getattr(client, method)(path, body, format="json")
    assert response.status_code == expected[persona], response.content[:300]
    if response.status_code >= 400:
        assert b"boccioni_1/" not in response.content  # no data leaks with a refusal


@pytest.mark.parametrize("persona", ["outsider", "foreign_robot"])
@pytest.mark.parametrize("path", ["/api/buildings/", "/api/tags/"])
def test_lists_show_nothing_of_buildings_one_may_not_see(
    world: World, persona: str, path: str
) -> None:
    response = client_for(world.principals[persona]).get(path)
    assert "boccioni_1" not in response.content.decode()
