"""The QR payload of an environmental tag: the paper's four comma separated fields.

Text form: ``cloud_location, zip, building_code, map_code``, for example
``http://127.0.0.1:8000, 56037, boccioni_1, CorridorA``. It names the sub-map a robot is
entering. ``encode_payload`` writes it with ", " between fields; ``parse_payload`` accepts
any whitespace around each field.

Field rules, shared by both directions so that ``parse_payload(encode_payload(p)) == p``:

- every field is printable ASCII without a comma: QR byte mode's default character set is
  ISO-8859-1 and readers guess UTF-8 inconsistently, so non-ASCII text would not survive;
- no field has surrounding whitespace (the parser would strip it);
- ``cloud_location`` is an ``http`` or ``https`` URL with a host;
- ``building_code`` and ``map_code`` are non-empty and contain no ``/``, because the Map ID
  ``building/map`` must split back into exactly those two codes;
- ``zip_code`` may be empty: a building abroad, or one whose operator does not publish it,
  still gets tags, and the zip is informative only (the building code identifies it).

The encoded text must fit QR version 3 at error-correction level L in byte mode
(``MAX_PAYLOAD_BYTES``), because smaller modules stop being readable at the distances a
robot reads tags from.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass
from urllib.parse import urlsplit

from maps.exceptions import TagPayloadError

MAX_PAYLOAD_BYTES = 53
"""Byte-mode capacity of a version 3 QR code at error-correction level L."""

FIELD_SEPARATOR = ", "
FIELD_NAMES = ("cloud_location", "zip_code", "building_code", "map_code")


@dataclass(frozen=True)
class TagPayload:
    """What a tag's QR code says: where the cloud is and which sub-map the robot enters."""

    cloud_location: str
    zip_code: str
    building_code: str
    map_code: str

    @property
    def map_id(self) -> str:
        """The Map ID ``building/map`` (docs/design.md, data model)."""
        return f"{self.building_code}/{self.map_code}"


def encode_payload(payload: TagPayload) -> str:
    """Return the QR text of ``payload``, fields joined by ", ".

    Raises ``TagPayloadError`` if a field breaks the module's field rules or the text is
    longer than ``MAX_PAYLOAD_BYTES``.
    """
    fields = astuple(payload)
    for name, value in zip(FIELD_NAMES, fields, strict=True):
        if value != value.strip():
            raise TagPayloadError(f"{name} has surrounding whitespace: {value!r}")
    _check_fields(payload)
    text = FIELD_SEPARATOR.join(fields)
    if len(text) > MAX_PAYLOAD_BYTES:  # ASCII checked above, so characters are bytes
        raise TagPayloadError(
            f"payload is {len(text)} bytes; QR version 3-L holds {MAX_PAYLOAD_BYTES}: {text!r}"
        )
    return text


def parse_payload(text: str) -> TagPayload:
    """Read the QR text of a tag; whitespace around each field is ignored.

    Raises ``TagPayloadError`` unless there are exactly four fields that follow the
    module's field rules. Length is not checked: a longer code printed elsewhere still
    reads, and rejecting it would help nobody.
    """
    fields = [field.strip() for field in text.split(",")]
    if len(fields) != len(FIELD_NAMES):
        raise TagPayloadError(f"expected {len(FIELD_NAMES)} comma separated fields: {text!r}")
    payload = TagPayload(*fields)
    _check_fields(payload)
    return payload


def _check_fields(payload: TagPayload) -> None:
    """Raise ``TagPayloadError`` naming the first field that breaks the field rules."""
    for name, value in zip(FIELD_NAMES, astuple(payload), strict=True):
        if "," in value:
            raise TagPayloadError(f"{name} contains a comma: {value!r}")
        if not (value.isascii() and value.isprintable()):
            raise TagPayloadError(f"{name} is not printable ASCII: {value!r}")
    _check_cloud_location(payload.cloud_location)
    for name, value in (("building_code", payload.building_code), ("map_code", payload.map_code)):
        if not value:
            raise TagPayloadError(f"{name} is empty")
        if "/" in value:
            raise TagPayloadError(f"{name} contains '/', which would split the Map ID: {value!r}")


def _check_cloud_location(url: str) -> None:
    """Raise ``TagPayloadError`` unless ``url`` is an http(s) URL with a host."""
    try:
        parts = urlsplit(url)
        hostname = parts.hostname
        parts.port  # noqa: B018  (raises ValueError on a port that is not a number)
    except ValueError as exc:  # an unbalanced IPv6 bracket, a bad port
        raise TagPayloadError(f"cloud_location is not a URL: {url!r}") from exc
    if parts.scheme not in ("http", "https") or not hostname:
        raise TagPayloadError(f"cloud_location must be an http(s) URL: {url!r}")
