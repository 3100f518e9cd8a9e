"""A dry-run upload: the upload's own checks and conversion, a preview to draw, nothing stored."""

from __future__ import annotations

from typing import Any

import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile

from maps.domain.mapfile import load_map_upload
from maps.domain.preview import PREVIEW_MAX_SIDE
from maps.models import Building, SubMap
from tests.conftest import client_for, make_submap, map_pgm, map_yaml
from tests.support.submap_uploads import BAD_UPLOADS, URL, pair, post, unread, zipped


def dry_run(user: User, data: dict[str, Any]) -> Any:
    return post(user, {**data, "dry_run": "true"})


def test_it_answers_the_preview_and_stores_nothing(building: Building, admin: User) -> None:
    response = dry_run(admin, pair(yaml=SimpleUploadedFile("m.yaml", map_yaml(mode="scale"))))
    assert response.status_code == 200, response.json()
    body = response.json()
    assert (body["dry_run"], body["map_id"], body["replaces"]) == (
        True,
        "boccioni_1/CorridorA",
        False,
    )
    assert (body["width"], body["height"], body["mode"]) == (40, 30, "scale")
    grid = load_map_upload(map_yaml(mode="scale"), {"map.pgm": map_pgm()}, 10**6).grid
    assert body["preview"]["data"] == grid.reshape(-1).tolist()
    assert body["counts"] == {
        "free": int((grid == 0).sum()),
        "occupied": int((grid == 100).sum()),
        "unknown": int((grid == -1).sum()),
        "other": int(((grid > 0) & (grid < 100)).sum()),
    }
    assert not SubMap.objects.exists()


def test_it_previews_a_zip_as_the_upload_reads_it(building: Building, admin: User) -> None:
    archive = zipped({"f/m.yaml": map_yaml(image="m.pgm"), "f/m.pgm": map_pgm(width=64)})
    body = dry_run(admin, {"code": "CorridorA", "archive": archive}).json()
    assert (body["image_name"], body["width"]) == ("m.pgm", 64)
    assert not SubMap.objects.exists()


def test_it_previews_before_a_code_is_chosen(building: Building, admin: User) -> None:
    body = dry_run(admin, pair(code=None)).json()
    assert (body["code"], body["map_id"], body["replaces"]) == (None, None, False)
    assert body["counts"] == {
        "free": 38 * 28 - 9,
        "occupied": 2 * 40 + 2 * 28,
        "unknown": 9,
        "other": 0,
    }
    assert post(admin, pair(code=None)).json() == {"code": ["This field is required."]}


def test_it_says_when_storing_would_replace_a_map(building: Building, admin: User) -> None:
    before = make_submap(building)
    response = dry_run(admin, pair(image=SimpleUploadedFile("map.pgm", map_pgm(width=50))))
    assert response.status_code == 200
    assert response.json()["replaces"] is True
    assert SubMap.objects.get().version == before.version


def test_a_large_map_is_previewed_downsampled_and_counted_whole(
    building: Building, admin: User
) -> None:
    image = SimpleUploadedFile("map.pgm", map_pgm(width=1300, height=700))
    body = dry_run(admin, pair(image=image)).json()
    info = body["preview"]["info"]
    assert body["preview_factor"] == 3
    assert (info["width"], info["height"]) == (434, 234)
    assert max(info["width"], info["height"]) <= PREVIEW_MAX_SIDE
    assert info["resolution"] == pytest.approx(0.15)
    assert sum(body["counts"].values()) == 1300 * 700


@pytest.mark.parametrize(("what", "change", "field"), BAD_UPLOADS, ids=[c[0] for c in BAD_UPLOADS])
def test_it_answers_the_field_errors_the_upload_would(
    building: Building, admin: User, what: str, change: dict[str, Any], field: str
) -> None:
    response = dry_run(admin, pair(**unread(change)))
    assert response.status_code == 400
    assert field in response.json(), response.json()
    assert not SubMap.objects.exists()


@pytest.mark.parametrize("persona", ["operator", "viewer", "outsider"])
def test_it_rejects_anyone_but_an_admin(
    building: Building, request: pytest.FixtureRequest, persona: str
) -> None:
    response = dry_run(request.getfixturevalue(persona), pair())
    assert response.status_code in (403, 404)
    assert b"boccioni_1/" not in response.content


def test_it_rejects_anonymous(building: Building) -> None:
    response = client_for(None).post(URL, {**pair(), "dry_run": "true"}, format="multipart")
    assert response.status_code == 401
