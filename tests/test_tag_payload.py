"""The QR payload codec of environmental tags (pure domain, no database)."""

from __future__ import annotations

from dataclasses import replace

import pytest
import qrcode
import qrcode.constants
import qrcode.exceptions

from maps.domain.tagpayload import MAX_PAYLOAD_BYTES, TagPayload, encode_payload, parse_payload
from maps.exceptions import TagPayloadError

PAPER_TEXT = "http://127.0.0.1:8000, 56037, boccioni_1, CorridorA"


def make_payload(**kwargs: str) -> TagPayload:
    kwargs.setdefault("cloud_location", "http://127.0.0.1:8000")
    kwargs.setdefault("zip_code", "56037")
    kwargs.setdefault("building_code", "boccioni_1")
    kwargs.setdefault("map_code", "CorridorA")
    return TagPayload(**kwargs)


def test_it_encodes_the_papers_example() -> None:
    assert encode_payload(make_payload()) == PAPER_TEXT


def test_the_map_id_joins_building_and_map_codes() -> None:
    assert make_payload().map_id == "boccioni_1/CorridorA"


@pytest.mark.parametrize(
    "text",
    [
        PAPER_TEXT,
        "http://127.0.0.1:8000,56037,boccioni_1,CorridorA",
        "  http://127.0.0.1:8000 ,56037 ,\tboccioni_1,   CorridorA\n",
    ],
)
def test_parse_ignores_spaces_around_fields(text: str) -> None:
    assert parse_payload(text) == make_payload()


@pytest.mark.parametrize(
    "payload",
    [
        make_payload(),
        make_payload(cloud_location="https://nav.example"),
        make_payload(zip_code="SW1A 1AA", map_code="Floor 2"),
        make_payload(zip_code=""),
    ],
)
def test_parse_reads_back_what_encode_wrote(payload: TagPayload) -> None:
    assert parse_payload(encode_payload(payload)) == payload


def test_an_empty_zip_code_is_allowed() -> None:
    assert (
        encode_payload(make_payload(zip_code=""))
        == "http://127.0.0.1:8000, , boccioni_1, CorridorA"
    )


def test_a_payload_of_exactly_53_bytes_is_accepted() -> None:
    payload = make_payload(map_code="C" * (MAX_PAYLOAD_BYTES - len(PAPER_TEXT) + len("CorridorA")))
    assert len(encode_payload(payload)) == MAX_PAYLOAD_BYTES


def test_a_payload_too_long_for_qr_version_3_l_raises() -> None:
    payload = make_payload(
        map_code="C" * (MAX_PAYLOAD_BYTES - len(PAPER_TEXT) + len("CorridorA") + 1)
    )
    with pytest.raises(TagPayloadError, match="53"):
        encode_payload(payload)


def test_53_bytes_is_what_qr_version_3_l_holds_in_byte_mode() -> None:
    def fits(length: int) -> bool:
        code = qrcode.QRCode(version=3, error_correction=qrcode.constants.ERROR_CORRECT_L)
        code.add_data(b"a" * length, optimize=0)
        try:
            code.make(fit=False)
        except qrcode.exceptions.DataOverflowError:
            return False
        return True

    assert fits(MAX_PAYLOAD_BYTES)
    assert not fits(MAX_PAYLOAD_BYTES + 1)


@pytest.mark.parametrize("field", ["cloud_location", "zip_code", "building_code", "map_code"])
def test_a_comma_in_a_field_raises(field: str) -> None:
    payload = replace(
        make_payload(), **{field: "http://a,b" if field == "cloud_location" else "a,b"}
    )
    with pytest.raises(TagPayloadError, match=f"{field} contains a comma"):
        encode_payload(payload)


@pytest.mark.parametrize("field", ["building_code", "map_code"])
def test_an_empty_building_or_map_code_raises(field: str) -> None:
    with pytest.raises(TagPayloadError, match=f"{field} is empty"):
        encode_payload(replace(make_payload(), **{field: ""}))


@pytest.mark.parametrize("field", ["building_code", "map_code"])
def test_a_slash_in_a_code_raises_because_the_map_id_would_not_split_back(field: str) -> None:
    with pytest.raises(TagPayloadError, match="Map ID"):
        encode_payload(replace(make_payload(), **{field: "a/b"}))


def test_non_ascii_text_raises_because_qr_readers_guess_its_encoding() -> None:
    with pytest.raises(TagPayloadError, match="ASCII"):
        encode_payload(make_payload(map_code="Corridoio_Città"))


def test_encode_refuses_a_field_with_surrounding_spaces_that_parse_would_drop() -> None:
    with pytest.raises(TagPayloadError, match="whitespace"):
        encode_payload(make_payload(map_code=" CorridorA"))


@pytest.mark.parametrize(
    "text",
    [
        "http://127.0.0.1:8000, 56037, boccioni_1",
        "http://127.0.0.1:8000, 56037, boccioni_1, CorridorA, extra",
        "",
    ],
)
def test_parse_requires_exactly_four_fields(text: str) -> None:
    with pytest.raises(TagPayloadError, match="4 comma"):
        parse_payload(text)


@pytest.mark.parametrize(
    "location",
    ["ftp://127.0.0.1", "127.0.0.1:8000", "http://", "http://[::1", "http://host:port", "cloud"],
)
def test_parse_requires_an_http_cloud_location(location: str) -> None:
    with pytest.raises(TagPayloadError, match="cloud_location"):
        parse_payload(f"{location}, 56037, boccioni_1, CorridorA")


def test_parse_accepts_an_https_cloud_location_with_a_path() -> None:
    payload = parse_payload("https://cloud.example.org:8443/nav, 56037, boccioni_1, CorridorA")
    assert payload.cloud_location == "https://cloud.example.org:8443/nav"
