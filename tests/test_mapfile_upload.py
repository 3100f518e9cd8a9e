"""Loading an uploaded YAML + image pair, or a zip of both, with every error at upload."""

from __future__ import annotations

import io
import struct
import zipfile

import numpy as np
import pytest

from maps.domain.mapfile import LoadedMap, load_map_archive, load_map_upload
from maps.exceptions import MapFileError
from tests.support.mapfiles import make_pgm, make_yaml, make_zip

LIMIT = 10**6
PGM = make_pgm([[0, 205, 254], [254, 254, 0]])


def upload(yaml: bytes | None = None, images: dict[str, bytes] | None = None) -> LoadedMap:
    return load_map_upload(
        yaml or make_yaml(), {"map.pgm": PGM} if images is None else images, LIMIT
    )


def upload_refused(
    yaml: bytes | None = None, images: dict[str, bytes] | None = None
) -> MapFileError:
    with pytest.raises(MapFileError) as caught:
        upload(yaml, images)
    return caught.value


def archive_refused(data: bytes, max_total_bytes: int = 1024 * 1024) -> MapFileError:
    with pytest.raises(MapFileError) as caught:
        load_map_archive(data, LIMIT, max_total_bytes)
    return caught.value


def understating(archive: bytes, size: int) -> bytes:
    """archive (one member) with both headers claiming the member unpacks to size bytes."""
    data = bytearray(archive)
    struct.pack_into("<I", data, 22, size)  # local file header
    struct.pack_into("<I", data, data.index(b"PK\x01\x02") + 24, size)  # central directory
    return bytes(data)


# load_map_upload


def test_it_loads_an_uploaded_pair() -> None:
    loaded = upload()
    assert loaded.grid.tolist() == [[0, 0, 100], [100, -1, 0]]
    assert (loaded.width, loaded.height) == (3, 2)


def test_it_keeps_the_image_bytes_as_uploaded() -> None:
    assert upload().image_bytes == PGM


def test_it_matches_an_image_path_starting_with_dot_slash() -> None:
    assert upload(make_yaml(image="./map.pgm")).image_bytes == PGM


def test_it_matches_an_image_path_with_folders() -> None:
    loaded = upload(make_yaml(image="maps/floor.pgm"), {"maps/floor.pgm": PGM, "floor.pgm": b""})
    assert loaded.image_bytes == PGM


def test_it_matches_a_bare_upload_name_by_base_name() -> None:
    assert upload(make_yaml(image="maps/floor.pgm"), {"floor.pgm": PGM}).image_bytes == PGM


def test_it_names_the_stored_image_by_its_base_name() -> None:
    loaded = upload(make_yaml(image="./maps/floor.pgm"), {"floor.pgm": PGM})
    assert loaded.image_name == loaded.meta.image == "floor.pgm"


def test_it_refuses_a_yaml_whose_image_is_not_in_the_upload() -> None:
    error = upload_refused(make_yaml(image="other.pgm"))
    assert (error.field, error.message) == ("image", "'other.pgm' is not in the upload")


def test_it_refuses_a_truncated_image_at_upload() -> None:
    assert upload_refused(images={"map.pgm": PGM[:-2]}).field == "image"


def test_it_refuses_an_image_over_the_pixel_limit_at_upload() -> None:
    big = make_pgm(np.zeros((1001, 1000)))
    assert upload_refused(images={"map.pgm": big}).field == "image"


def test_it_refuses_bad_metadata_at_upload() -> None:
    assert upload_refused(make_yaml(free_thresh=0.9)).field == "free_thresh"


# load_map_archive


def test_it_loads_a_zipped_pair() -> None:
    loaded = load_map_archive(make_zip({"map.yaml": make_yaml(), "map.pgm": PGM}), LIMIT)
    assert loaded.grid.tolist() == [[0, 0, 100], [100, -1, 0]]
    assert (loaded.image_name, loaded.image_bytes) == ("map.pgm", PGM)


def test_it_finds_the_pair_in_a_sub_folder() -> None:
    archive = make_zip(
        {"maps/": b"", "maps/floor.yml": make_yaml(image="floor.pgm"), "maps/floor.pgm": PGM}
    )
    assert load_map_archive(archive, LIMIT).image_name == "floor.pgm"


def test_it_resolves_the_image_path_against_the_yaml_folder() -> None:
    yaml = make_yaml(image="../images/./floor.pgm")
    archive = make_zip({"maps/floor.yaml": yaml, "images/floor.pgm": PGM, "floor.pgm": b""})
    assert load_map_archive(archive, LIMIT).image_bytes == PGM


def test_it_ignores_the_resource_forks_macos_adds() -> None:
    archive = make_zip({"map.yaml": make_yaml(), "map.pgm": PGM, "__MACOSX/._map.yaml": b"\0"})
    assert load_map_archive(archive, LIMIT).image_bytes == PGM


def test_it_tolerates_other_files_beside_the_pair() -> None:
    archive = make_zip({"map.yaml": make_yaml(), "map.pgm": PGM, "README.txt": b"floor 1"})
    assert load_map_archive(archive, LIMIT).image_bytes == PGM


@pytest.mark.parametrize("data", [b"", b"not a zip at all", b"PK\x03\x04" + bytes(40)], ids=repr)
def test_it_refuses_data_that_is_not_a_zip(data: bytes) -> None:
    assert archive_refused(data).field == "archive"


ESCAPING_NAMES = [
    "../map.pgm",
    "maps/../../map.pgm",
    "/etc/map.pgm",
    "maps\\..\\map.pgm",
    "..\\map.pgm",
    "C:/maps/map.pgm",
    "c:map.pgm",
]


@pytest.mark.parametrize("name", ESCAPING_NAMES)
def test_it_refuses_a_member_name_that_escapes_the_archive(name: str) -> None:
    error = archive_refused(make_zip({"map.yaml": make_yaml(), "map.pgm": PGM, name: b"x"}))
    assert error.field == "archive"
    assert repr(name) in error.message


# zipfile cuts a member's name at NUL, so only a pair's image name can hold one.
CONTROL_NAMES = ["map\r\n.pgm", "map\n.pgm", "map\t.pgm", "map\u2028.pgm", "\u202emap.pgm"]


@pytest.mark.parametrize("name", CONTROL_NAMES, ids=repr)
def test_it_refuses_a_member_name_with_a_control_character(name: str) -> None:
    error = archive_refused(make_zip({"map.yaml": make_yaml(image=name), name: PGM}))
    assert error.field == "archive"
    assert repr(name) in error.message


@pytest.mark.parametrize("name", [*CONTROL_NAMES, "map\x00.pgm"], ids=repr)
def test_it_refuses_an_uploaded_image_name_with_a_control_character(name: str) -> None:
    assert upload_refused(make_yaml(image=name), {name: PGM}).field == "image"


def test_it_refuses_a_zip_bomb_by_its_declared_sizes() -> None:
    archive = make_zip(
        {"map.yaml": make_yaml(), "map.pgm": PGM, "bomb.bin": bytes(2 * 1024 * 1024)}
    )
    assert len(archive) < 10_000
    assert archive_refused(archive, max_total_bytes=1024 * 1024).field == "archive"


def test_it_refuses_a_member_that_inflates_past_its_declared_size() -> None:
    archive = understating(make_zip({"map.yaml": make_yaml() + b"#" * 100_000}), 100)
    assert archive_refused(archive).field == "archive"


def test_it_refuses_a_member_whose_data_is_corrupt() -> None:
    data = bytearray(make_zip({"map.yaml": make_yaml(), "map.pgm": PGM}))
    data[40:60] = bytes(20)  # inside the YAML's compressed data
    assert archive_refused(bytes(data)).field == "archive"


def test_it_refuses_an_encrypted_member() -> None:
    data = bytearray(make_zip({"map.yaml": make_yaml(), "map.pgm": PGM}))
    data[6] |= 1  # the local header's "encrypted" flag
    data[data.index(b"PK\x01\x02") + 8] |= 1  # and the central directory's
    assert archive_refused(bytes(data)).field == "archive"


def test_it_refuses_an_archive_without_a_yaml() -> None:
    assert archive_refused(make_zip({"map.pgm": PGM})).field == "archive"


def test_it_refuses_an_archive_with_several_yamls() -> None:
    archive = make_zip({"a.yaml": make_yaml(), "b/c.yml": make_yaml(), "map.pgm": PGM})
    assert archive_refused(archive).field == "archive"


def test_it_refuses_an_archive_whose_image_is_missing() -> None:
    error = archive_refused(make_zip({"map.yaml": make_yaml(image="other.pgm"), "map.pgm": PGM}))
    assert (error.field, error.message) == ("image", "'other.pgm' is not in the upload")


@pytest.mark.parametrize("image", ["../map.pgm", "/map.pgm", "maps/../../map.pgm"])
def test_it_refuses_an_image_path_leading_out_of_the_archive(image: str) -> None:
    archive = make_zip({"map.yaml": make_yaml(image=image), "map.pgm": PGM})
    assert archive_refused(archive).field == "image"


def test_it_refuses_a_truncated_image_in_an_archive() -> None:
    archive = make_zip({"map.yaml": make_yaml(), "map.pgm": PGM[:-2]})
    assert archive_refused(archive).field == "image"


def test_it_reads_stored_as_well_as_deflated_members() -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        archive.writestr("map.yaml", make_yaml())
        archive.writestr("map.pgm", PGM)
    assert load_map_archive(buffer.getvalue(), LIMIT).image_bytes == PGM
