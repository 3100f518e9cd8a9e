"""Map YAML metadata: validation, parsing, writing back, and the content version."""

from __future__ import annotations

import hashlib
import math
from dataclasses import replace
from typing import Any

import pytest

from maps.domain.mapfile import (
    MapMetadata,
    content_version,
    map_yaml_text,
    parse_map_yaml,
    validate_metadata,
)
from maps.exceptions import MapFileError
from tests.support.mapfiles import MISSING, make_fields, make_meta, make_yaml


def field_refused(**kwargs: Any) -> str:
    with pytest.raises(MapFileError) as caught:
        validate_metadata(make_fields(**kwargs))
    return caught.value.field


def yaml_refused(text: bytes | str) -> str:
    with pytest.raises(MapFileError) as caught:
        parse_map_yaml(text)
    return caught.value.field


# validate_metadata


def test_it_reads_every_map_server_key() -> None:
    fields = make_fields(
        image="floor.pgm",
        resolution=0.1,
        origin=[-1.5, 2.0, 0.25],
        occupied_thresh=0.7,
        free_thresh=0.2,
        negate=1,
        mode="scale",
    )
    assert validate_metadata(fields) == MapMetadata(
        image="floor.pgm",
        resolution=0.1,
        origin=(-1.5, 2.0, 0.25),
        occupied_thresh=0.7,
        free_thresh=0.2,
        negate=True,
        mode="scale",
    )


def test_it_defaults_the_mode_to_trinary() -> None:
    assert validate_metadata(make_fields()).mode == "trinary"


@pytest.mark.parametrize("mode", ["Scale", "RAW", "Trinary"])
def test_it_reads_the_mode_in_any_case_as_map_server_does(mode: str) -> None:
    assert validate_metadata(make_fields(mode=mode)).mode == mode.lower()


@pytest.mark.parametrize(
    ("negate", "expected"), [(0, False), (1, True), (False, False), (True, True)]
)
def test_it_reads_negate_as_0_1_or_a_bool(negate: object, expected: bool) -> None:
    assert validate_metadata(make_fields(negate=negate)).negate is expected


def test_it_reads_integer_numbers_as_floats() -> None:
    meta = validate_metadata(make_fields(resolution=1, origin=[1, -2, 0], occupied_thresh=1))
    assert (meta.resolution, meta.origin, meta.occupied_thresh) == (1.0, (1.0, -2.0, 0.0), 1.0)
    assert all(isinstance(value, float) for value in (meta.resolution, *meta.origin))


def test_it_accepts_thresholds_at_0_and_1() -> None:
    meta = validate_metadata(make_fields(free_thresh=0, occupied_thresh=1))
    assert (meta.free_thresh, meta.occupied_thresh) == (0.0, 1.0)


def test_it_ignores_keys_map_server_does_not_know() -> None:
    assert validate_metadata(make_fields(comment="lab", extra=[1, 2])) == make_meta()


BAD_FIELDS: list[tuple[str, dict[str, Any], str]] = [
    ("image missing", {"image": MISSING}, "image"),
    ("image empty", {"image": ""}, "image"),
    ("image blank", {"image": "   "}, "image"),
    ("image a number", {"image": 5}, "image"),
    ("image null", {"image": None}, "image"),
    ("image a list", {"image": ["map.pgm"]}, "image"),
    ("resolution missing", {"resolution": MISSING}, "resolution"),
    ("resolution as text", {"resolution": "0.05"}, "resolution"),
    ("resolution a bool", {"resolution": True}, "resolution"),
    ("resolution null", {"resolution": None}, "resolution"),
    ("resolution nan", {"resolution": math.nan}, "resolution"),
    ("resolution inf", {"resolution": math.inf}, "resolution"),
    ("resolution too big for a float", {"resolution": 10**400}, "resolution"),
    ("resolution zero", {"resolution": 0}, "resolution"),
    ("resolution negative", {"resolution": -0.05}, "resolution"),
    ("origin missing", {"origin": MISSING}, "origin"),
    ("origin of two numbers", {"origin": [0.0, 0.0]}, "origin"),
    ("origin of four numbers", {"origin": [0.0, 0.0, 0.0, 0.0]}, "origin"),
    ("origin as text", {"origin": "0 0 0"}, "origin"),
    ("origin a mapping", {"origin": {"x": 0, "y": 0, "yaw": 0}}, "origin"),
    ("origin holding text", {"origin": [0.0, "1", 0.0]}, "origin"),
    ("origin holding a bool", {"origin": [0.0, True, 0.0]}, "origin"),
    ("origin holding nan", {"origin": [0.0, 0.0, math.nan]}, "origin"),
    ("origin holding inf", {"origin": [-math.inf, 0.0, 0.0]}, "origin"),
    ("occupied_thresh missing", {"occupied_thresh": MISSING}, "occupied_thresh"),
    ("occupied_thresh as text", {"occupied_thresh": "0.65"}, "occupied_thresh"),
    ("occupied_thresh a bool", {"occupied_thresh": True}, "occupied_thresh"),
    ("occupied_thresh nan", {"occupied_thresh": math.nan}, "occupied_thresh"),
    ("occupied_thresh above 1", {"occupied_thresh": 1.5}, "occupied_thresh"),
    ("occupied_thresh below 0", {"occupied_thresh": -0.1}, "occupied_thresh"),
    ("free_thresh missing", {"free_thresh": MISSING}, "free_thresh"),
    ("free_thresh as text", {"free_thresh": "low"}, "free_thresh"),
    ("free_thresh inf", {"free_thresh": math.inf}, "free_thresh"),
    ("free_thresh below 0", {"free_thresh": -0.1}, "free_thresh"),
    ("free_thresh above 1", {"free_thresh": 1.01}, "free_thresh"),
    ("free_thresh at occupied_thresh", {"free_thresh": 0.65}, "free_thresh"),
    ("free_thresh above occupied_thresh", {"free_thresh": 0.9}, "free_thresh"),
    ("free_thresh equal in float32", {"free_thresh": 0.65 - 1e-12}, "free_thresh"),
    ("negate missing", {"negate": MISSING}, "negate"),
    ("negate 2", {"negate": 2}, "negate"),
    ("negate -1", {"negate": -1}, "negate"),
    ("negate a float", {"negate": 0.0}, "negate"),
    ("negate as text", {"negate": "yes"}, "negate"),
    ("negate null", {"negate": None}, "negate"),
    ("mode unknown", {"mode": "fancy"}, "mode"),
    ("mode a number", {"mode": 1}, "mode"),
    ("mode null", {"mode": None}, "mode"),
]


@pytest.mark.parametrize(("what", "change", "field"), BAD_FIELDS, ids=[c[0] for c in BAD_FIELDS])
def test_it_refuses_bad_metadata_naming_the_field(
    what: str, change: dict[str, Any], field: str
) -> None:
    assert field_refused(**change) == field


# parse_map_yaml


def test_it_parses_a_map_server_yaml_document() -> None:
    text = b"image: map.pgm\nresolution: 0.05\norigin: [-10.0, -5.5, 0.0]\n"
    text += b"negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    assert parse_map_yaml(text) == make_meta(origin=(-10.0, -5.5, 0.0))


def test_it_parses_text_as_well_as_bytes() -> None:
    assert parse_map_yaml(make_yaml().decode()) == parse_map_yaml(make_yaml())


def test_it_reads_yaml_booleans_for_negate() -> None:
    assert parse_map_yaml(make_yaml(negate=True)).negate is True


@pytest.mark.parametrize(
    "text",
    [
        b"a: [1, \n",
        b"image: map.pgm\n  bad: indent\n : x",
        b"\xff\xfe\xfa not utf",
        b"a: 1\n---\nb: 2\n",
    ],
    ids=["unclosed list", "bad indent", "not utf-8", "two documents"],
)
def test_it_refuses_yaml_that_does_not_parse(text: bytes) -> None:
    assert yaml_refused(text) == "yaml"


@pytest.mark.parametrize(
    "text", [b"- 1\n- 2\n", b"just text\n", b"", b"# only a comment\n"], ids=str
)
def test_it_refuses_yaml_that_is_not_a_mapping(text: bytes) -> None:
    assert yaml_refused(text) == "yaml"


@pytest.mark.slow
def test_it_refuses_yaml_nested_deeper_than_the_parser_can_follow() -> None:
    assert yaml_refused(b"[" * 100_000) == "yaml"


def test_it_refuses_a_yaml_file_over_a_mebibyte() -> None:
    assert yaml_refused(make_yaml() + b"#" * (1024 * 1024)) == "yaml"


def test_it_names_the_metadata_key_once_the_yaml_parses() -> None:
    assert yaml_refused(make_yaml(resolution="fine")) == "resolution"


# map_yaml_text


def test_it_writes_keys_in_map_saver_order() -> None:
    keys = [line.split(":")[0] for line in map_yaml_text(make_meta()).splitlines()]
    assert keys == [
        "image",
        "mode",
        "resolution",
        "origin",
        "negate",
        "occupied_thresh",
        "free_thresh",
    ]


@pytest.mark.parametrize(("negate", "line"), [(False, "negate: 0"), (True, "negate: 1")])
def test_it_writes_negate_as_0_or_1(negate: bool, line: str) -> None:
    assert line in map_yaml_text(make_meta(negate=negate)).splitlines()


def test_it_writes_the_origin_on_one_line() -> None:
    text = map_yaml_text(make_meta(origin=(-10.0, 2.5, 0.5)))
    assert "origin: [-10.0, 2.5, 0.5]" in text.splitlines()


AWKWARD_METADATA = [
    make_meta(resolution=0.1 + 0.2),
    make_meta(resolution=1e-7, origin=(1e20, -3.0000000000000004, math.pi)),
    make_meta(resolution=5e-324, origin=(-0.0, 123456789.123456789, -math.pi)),
    make_meta(occupied_thresh=1.0, free_thresh=0.0),
    make_meta(occupied_thresh=0.65 + 1e-9, free_thresh=0.196 - 1e-9),
    make_meta(negate=True, mode="scale"),
    make_meta(mode="raw"),
    make_meta(image="maps/floor 1: east #2.pgm"),
    make_meta(image="yes"),
    make_meta(image="0.5"),
]


@pytest.mark.parametrize("meta", AWKWARD_METADATA, ids=repr)
def test_it_writes_yaml_that_reads_back_identically(meta: MapMetadata) -> None:
    assert parse_map_yaml(map_yaml_text(meta)) == meta


# content_version


def test_content_version_is_a_sha256_hex_digest() -> None:
    version = content_version(b"image", make_meta())
    assert len(version) == len(hashlib.sha256().hexdigest())
    assert int(version, 16) >= 0


def test_content_version_is_stable_for_the_same_image_and_metadata() -> None:
    assert content_version(b"image", make_meta()) == content_version(b"image", make_meta())


def test_content_version_changes_with_the_image_bytes() -> None:
    assert content_version(b"image", make_meta()) != content_version(b"imagf", make_meta())


METADATA_CHANGES: list[tuple[str, Any]] = [
    ("image", "other.pgm"),
    ("resolution", math.nextafter(0.05, 1.0)),
    ("origin", (1.0, 0.0, 0.0)),
    ("origin", (0.0, 1.0, 0.0)),
    ("origin", (0.0, 0.0, 1.0)),
    ("occupied_thresh", 0.66),
    ("free_thresh", 0.2),
    ("negate", True),
    ("mode", "scale"),
    ("mode", "raw"),
]


@pytest.mark.parametrize(
    ("field", "value"), METADATA_CHANGES, ids=[f"{f}={v}" for f, v in METADATA_CHANGES]
)
def test_content_version_changes_with_each_metadata_field(field: str, value: Any) -> None:
    meta = make_meta()
    changed = replace(meta, **{field: value})
    assert content_version(b"image", changed) != content_version(b"image", meta)
