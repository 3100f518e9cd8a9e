"""Sub-map versions through the API: history with who, when and why; old versions
readable; comparison; rollback; bundles and ETags naming the version; tags surviving a
new version and flagged when they stand in an occupied cell; a change prepared on a
version no longer current refused."""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest
from django.contrib.auth.models import User
from PIL import Image

from maps import services, versions
from maps.domain.mapfile import load_map_upload
from maps.domain.versions import Reason, map_ref, split_map_ref
from maps.exceptions import VersionConflict
from maps.models import Building, SubMap
from tests.conftest import client_for, make_robot, make_submap, make_tag, map_pgm, map_yaml

BASE = "/api/buildings/boccioni_1/maps/CorridorA"


def pgm_with_box(rows: slice, cols: slice) -> bytes:
    """``map_pgm()`` with a block of occupied pixels (image rows count from the top)."""
    pixels = np.array(Image.open(io.BytesIO(map_pgm())))
    pixels[rows, cols] = 0
    out = io.BytesIO()
    Image.fromarray(pixels, "L").save(out, "PPM")
    return out.getvalue()


def upload(client: Any, image: bytes, note: str = "") -> Any:
    files = {
        "code": "CorridorA",
        "image": _file(image, "map.pgm"),
        "yaml": _file(map_yaml(), "map.yaml"),
        "note": note,
        "replace": "true",
    }
    return client.post("/api/buildings/boccioni_1/maps/", files, format="multipart")


def _file(data: bytes, name: str) -> Any:
    from django.core.files.uploadedfile import SimpleUploadedFile

    return SimpleUploadedFile(name, data)


@pytest.fixture
def corridor(building: Building, admin: User) -> SubMap:
    assert upload(client_for(admin), map_pgm(), "first survey").status_code == 201
    return SubMap.objects.get(code="CorridorA")


def test_an_upload_is_version_1_with_who_when_and_why(corridor: SubMap, viewer: User) -> None:
    body = client_for(viewer).get(f"{BASE}/versions/").json()
    assert body["current"] == 1
    [first] = body["versions"]
    assert first["number"] == 1
    assert first["reason"] == "upload"
    assert first["author"] == "admin"
    assert first["note"] == "first survey"
    assert first["created"]
    assert first["map_ref"] == "boccioni_1/CorridorA@v1"


def test_a_new_upload_is_a_new_version_and_the_old_one_stays_readable(
    corridor: SubMap, admin: User
) -> None:
    client = client_for(admin)
    assert upload(client, pgm_with_box(slice(10, 14), slice(10, 14)), "cabinet").status_code == 200
    body = client.get(f"{BASE}/versions/").json()
    assert body["current"] == 2
    assert [v["number"] for v in body["versions"]] == [2, 1]
    assert client.get(f"{BASE}/versions/1/image").content == map_pgm()
    assert client.get(f"{BASE}/image").content != map_pgm()
    old_grid = client.get(f"{BASE}/versions/1/grid").json()
    assert old_grid["info"]["width"] == 40


def test_the_same_map_uploaded_again_makes_no_version(corridor: SubMap, admin: User) -> None:
    upload(client_for(admin), map_pgm())
    assert client_for(admin).get(f"{BASE}/versions/").json()["current"] == 1


def test_a_metadata_edit_is_a_version(corridor: SubMap, admin: User) -> None:
    client = client_for(admin)
    client.patch(f"{BASE}/", {"origin": [1.0, 2.0, 0.0]}, format="json")
    assert client.get(f"{BASE}/versions/").json()["versions"][0]["reason"] == "edit"
    client.patch(f"{BASE}/", {"name": "Corridor A"}, format="json")
    assert client.get(f"{BASE}/versions/").json()["current"] == 2  # a name is no version


def test_comparing_counts_the_cells_added_and_removed(corridor: SubMap, admin: User) -> None:
    client = client_for(admin)
    upload(client, pgm_with_box(slice(10, 14), slice(10, 15)))  # 4 x 5 cells
    body = client.get(f"{BASE}/versions/compare?from=1&to=2").json()
    assert (body["added"], body["removed"]) == (20, 0)
    rows = {row for row, _ in body["cells"]["added"]}
    assert rows == {30 - 1 - r for r in range(10, 14)}  # grid row 0 is the image's bottom
    back = client.get(f"{BASE}/versions/compare?from=2&to=1").json()
    assert (back["added"], back["removed"]) == (0, 20)


def test_comparing_asks_for_both_numbers(corridor: SubMap, admin: User) -> None:
    assert client_for(admin).get(f"{BASE}/versions/compare?from=1").status_code == 400
    assert client_for(admin).get(f"{BASE}/versions/compare?from=1&to=9").status_code == 404


def test_a_rollback_is_a_new_version_holding_the_old_map(corridor: SubMap, admin: User) -> None:
    client = client_for(admin)
    upload(client, pgm_with_box(slice(10, 14), slice(10, 15)))
    answer = client.post(f"{BASE}/versions/1/rollback", {"note": "cabinet gone"}, format="json")
    assert answer.status_code == 201
    assert answer.json()["number"] == 3
    assert answer.json()["reason"] == "rollback"
    assert answer.json()["based_on"] == 1
    assert client.get(f"{BASE}/image").content == map_pgm()
    assert client.get(f"{BASE}/").json()["version"] == 3


def test_only_admins_roll_back(corridor: SubMap, operator: User, outsider: User) -> None:
    assert client_for(operator).post(f"{BASE}/versions/1/rollback").status_code == 403
    assert client_for(outsider).post(f"{BASE}/versions/1/rollback").status_code == 404


def test_it_rejects_outsider(corridor: SubMap, outsider: User) -> None:
    for path in ("versions/", "versions/1/", "versions/1/image", "versions/compare?from=1&to=1"):
        assert client_for(outsider).get(f"{BASE}/{path}").status_code == 404
    assert client_for(None).get(f"{BASE}/versions/").status_code in (401, 403)


def test_the_bundle_and_its_etag_name_the_version(corridor: SubMap, admin: User) -> None:
    token = make_robot(name="r1", buildings=[corridor.building])[1]
    robot = client_for(token)
    first = robot.get(f"{BASE}/bundle")
    assert first.json()["revision"] == 1
    assert first.json()["map_ref"] == "boccioni_1/CorridorA@v1"
    assert first["ETag"].startswith('"v1-')
    upload(client_for(admin), pgm_with_box(slice(10, 14), slice(10, 15)))
    again = robot.get(f"{BASE}/bundle", headers={"If-None-Match": first["ETag"]})
    assert again.status_code == 200
    assert again["ETag"].startswith('"v2-')


def test_tags_survive_a_new_version_and_buried_ones_are_flagged(
    corridor: SubMap, admin: User
) -> None:
    # A tag on the inside face of the west wall (x = 0.05 m), facing east, at y = 0.5 m.
    make_tag(corridor, marker_id=4, x=0.05, y=0.5, yaw=0.0)
    client = client_for(admin)
    assert client.get(f"{BASE}/versions/").json()["buried_tags"] == []
    # A cabinet now stands against that wall, in front of the tag (image rows from the top).
    upload(client, pgm_with_box(slice(30 - 14, 30 - 6), slice(1, 4)))
    body = client.get(f"{BASE}/versions/").json()
    assert body["current"] == 2
    assert body["buried_tags"] == [4]
    assert [t["marker_id"] for t in client.get("/api/tags/?map=CorridorA").json()] == [4]


def test_a_change_made_on_an_old_version_is_refused_and_nothing_is_lost(
    corridor: SubMap, admin: User
) -> None:
    loaded = load_map_upload(map_yaml(), {"map.pgm": pgm_with_box(slice(5, 6), slice(5, 6))}, 10**7)
    upload(client_for(admin), pgm_with_box(slice(10, 14), slice(10, 15)))  # now at 2
    with pytest.raises(VersionConflict) as refused:
        versions.publish(corridor, loaded, Reason.CHANGE, based_on=1, author=admin)
    assert (refused.value.based_on, refused.value.current) == (1, 2)
    assert "v2" in str(refused.value)
    assert SubMap.objects.get(pk=corridor.pk).revision == 2
    assert corridor.versions.count() == 2
    made = versions.publish(corridor, loaded, Reason.CHANGE, based_on=2, author=admin)
    assert made.number == 3


def test_a_sub_map_made_before_versions_is_version_1(building: Building) -> None:
    submap = make_submap(building, code="Atrium1")
    assert submap.revision == 1
    assert [v.reason for v in submap.versions.all()] == ["upload"]
    assert services.bundle_of(submap)["map_ref"] == "boccioni_1/Atrium1@v1"


def test_version_names_read_back() -> None:
    assert split_map_ref(map_ref("b/CorridorA", 12)) == ("b/CorridorA", 12)
    assert split_map_ref("b/CorridorA") == ("b/CorridorA", None)
    assert split_map_ref("b/CorridorA@v0") == ("b/CorridorA@v0", None)


def test_a_version_is_its_number_in_every_answer_and_the_hash_is_named_so(
    corridor: SubMap, admin: User
) -> None:
    client = client_for(admin)
    assert upload(client, pgm_with_box(slice(5, 9), slice(5, 9))).status_code == 200
    submap = client.get(f"{BASE}/").json()
    assert submap["version"] == 2
    assert submap["content_hash"] == SubMap.objects.get(pk=corridor.pk).version
    newest = client.get(f"{BASE}/versions/").json()["versions"][0]
    assert newest["number"] == 2
    assert "version" not in newest
    assert len(newest["content_hash"]) >= 12
    missing = client.get(f"{BASE}/versions/9/image").json()
    assert "v9" in str(missing)
