"""Artwork of an environmental tag: one drawing for the printed tag and the simulated camera.

Layout contract
===============

A tag is a flat plate standing in a wall plane. Looking at its face (standing in front of
it, where its outward normal points), the fiducial marker is on the LEFT and the QR code
on the RIGHT, both squares of side ``size`` metres (the tag's physical size, 0.06 m by
default) with their centres at the same height. Around and between the two codes runs a
white band ``QUIET_ZONE * size`` wide (0.25 size), so the plate face is::

        |<--------------------- 2.75 size --------------------->|
        +-------------------------------------------------------+  ---
        |                     0.25 size                         |   ^
        |          +-----------+             +-----------+      |   |
        | 0.25 size|  marker   |  0.25 size  |  QR code  | 0.25 |  1.5 size
        |          |     *     |             |     +     | size |   |
        |          +-----------+             +-----------+      |   |
        |                     0.25 size                         |   v
        +-------------------------------------------------------+  ---

- ``*`` is the marker centre, the tag's stored pose ``(x, y, yaw)`` (docs/design.md); yaw is
  the outward normal. On the face it is ``0.75 size`` from the left edge and from the top
  edge; the face is centred on it vertically.
- ``+`` is the QR centre: the marker centre plus ``qr_offset(size) = 1.25 size`` along the
  plate's right axis, which in the sub-map frame is ``(-sin yaw, cos yaw)`` (the normal
  turned +90 degrees; ``plate_right_axis``, ``qr_centre``).
- For the default 0.06 m: face 165 x 90 mm, QR centre 75 mm right of the marker centre,
  white band 15 mm, which is 7.25 QR modules (the standard asks for 4) and 2 marker cells
  (ArUco detection wants at least 1).
- The marker is an OpenCV ArUco marker from a predefined dictionary chosen by name
  (``DICT_APRILTAG_36h11`` by default), black border included, drawn edge to edge over
  ``size``. The QR code is version 3 (29 modules) at error-correction level L, its module
  grid drawn edge to edge over ``size``; its quiet zone is the white band.

``tag_face`` draws exactly this face (no text) at a chosen pixel density for the simulated
camera; ``render_tag_png`` and ``render_tag_pdf`` print it at true physical size with a
white margin, crop marks and, below the face, the Map ID, ``marker <id> (<size> mm)`` and
``to <linked map>``.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cache

import cv2
import numpy as np
import qrcode
import qrcode.constants
import qrcode.exceptions
from numpy.typing import NDArray
from PIL import Image, ImageDraw, ImageFont

from maps.domain.tagpayload import MAX_PAYLOAD_BYTES
from maps.exceptions import TagPayloadError

DEFAULT_DICTIONARY = "DICT_APRILTAG_36h11"
DEFAULT_SIZE = 0.06
"""Side of each code in metres (docs/design.md: the tag's physical size)."""

MIN_SIZE = 0.01
MAX_SIZE = 0.25
"""Tags are printed at true size at 300 dpi: a 25 cm tag (a plate 69 x 38 cm, read from
many metres) is already a 40-megapixel print; larger ones are refused."""

QUIET_ZONE = 0.25
"""White band around and between the two codes, as a fraction of ``size``."""

QR_VERSION = 3
QR_MODULES = 17 + 4 * QR_VERSION  # 29: modules per side, without quiet zone

FACE_WIDTH = 2 + 3 * QUIET_ZONE  # 2.75, in units of size
FACE_HEIGHT = 1 + 2 * QUIET_ZONE  # 1.5, in units of size

INCH = 0.0254
A4 = (0.210, 0.297)  # metres, portrait
PRINT_MARGIN = 0.005  # white beyond the face, up to the crop marks, in metres
PAGE_MARGIN = 0.008  # keeps tags out of the area most printers cannot reach
CROP_MARK = 0.004  # length of each crop mark arm, in metres
TEXT_POINTS = (12.0, 10.0, 10.0)  # Map ID, marker line, link line

Grey = NDArray[np.uint8]


# --- geometry --------------------------------------------------------------------------


def qr_offset(size: float) -> float:
    """Distance in metres from the marker centre to the QR centre, along the right axis."""
    return (1 + QUIET_ZONE) * size


def face_size(size: float) -> tuple[float, float]:
    """Nominal ``(width, height)`` of the plate face in metres for codes of side ``size``."""
    return FACE_WIDTH * size, FACE_HEIGHT * size


def plate_right_axis(yaw: float) -> tuple[float, float]:
    """Unit vector, in the sub-map frame, of the face's rightward axis for a tag facing ``yaw``."""
    return -math.sin(yaw), math.cos(yaw)


def qr_centre(x: float, y: float, yaw: float, size: float) -> tuple[float, float]:
    """Sub-map position of the QR centre of a tag whose marker centre is at ``(x, y)``."""
    right_x, right_y = plate_right_axis(yaw)
    offset = qr_offset(size)
    return x + offset * right_x, y + offset * right_y


# --- the two codes ---------------------------------------------------------------------


@cache
def aruco_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The predefined OpenCV dictionary called ``name`` (e.g. ``"DICT_APRILTAG_36h11"``).

    Raises ``TagPayloadError`` for a name OpenCV does not define.
    """
    ident = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(ident, int):
        raise TagPayloadError(f"unknown ArUco dictionary: {name!r}")
    return cv2.aruco.getPredefinedDictionary(ident)


def marker_id_limit(dictionary: str) -> int:
    """How many marker ids ``dictionary`` holds (ids run from 0 to this minus one).

    Raises ``TagPayloadError`` for a name OpenCV does not define.
    """
    return int(aruco_dictionary(dictionary).bytesList.shape[0])


def marker_image(marker_id: int, dictionary: str, pixels: int) -> Grey:
    """The marker, ``pixels`` square, black border included and no white margin.

    Cells are scaled with nearest neighbour, so every pixel is 0 or 255. Raises
    ``TagPayloadError`` if ``marker_id`` is not in the dictionary, ``ValueError`` if
    ``pixels`` is smaller than the marker's cell count.
    """
    vocabulary = aruco_dictionary(dictionary)
    if not 0 <= marker_id < len(vocabulary.bytesList):
        raise TagPayloadError(
            f"marker id {marker_id} is not in {dictionary} (0..{len(vocabulary.bytesList) - 1})"
        )
    cells = vocabulary.markerSize + 2  # one border cell on each side
    grid = cv2.aruco.generateImageMarker(vocabulary, marker_id, cells, borderBits=1)
    return _scale_nearest(grid == 0, pixels)


def qr_image(payload: str, pixels: int, version: int = QR_VERSION) -> Grey:
    """The version 3-L QR code of ``payload``, ``pixels`` square, without quiet zone.

    Modules are scaled with nearest neighbour (exact when ``pixels`` is a multiple of 29).
    ``version`` other than 3 draws that version instead, at level L, for experiments on
    reading range (printed tags are always version 3). Raises ``TagPayloadError`` if the
    UTF-8 payload exceeds ``MAX_PAYLOAD_BYTES`` (or, for another version, what that
    version holds), ``ValueError`` if ``pixels`` is smaller than the module count.
    """
    data = payload.encode("utf-8")
    if version == QR_VERSION and len(data) > MAX_PAYLOAD_BYTES:
        raise TagPayloadError(f"payload is {len(data)} bytes; QR 3-L holds {MAX_PAYLOAD_BYTES}")
    code = qrcode.QRCode(
        version=version, error_correction=qrcode.constants.ERROR_CORRECT_L, border=0
    )
    code.add_data(data, optimize=0)  # one segment: byte mode capacity is what we promise
    try:
        code.make(fit=False)  # keep the version even for short payloads: one module size
    except qrcode.exceptions.DataOverflowError as exc:
        raise TagPayloadError(
            f"payload is {len(data)} bytes; QR {version}-L cannot hold it"
        ) from exc
    return _scale_nearest(np.array(code.get_matrix(), dtype=bool), pixels)


def _scale_nearest(dark: NDArray[np.bool_], pixels: int) -> Grey:
    """Grey image ``pixels`` square of the boolean grid ``dark`` (True is black)."""
    cells = dark.shape[0]
    if pixels < cells:
        raise ValueError(f"{pixels} pixels cannot hold {cells} cells")
    index = np.arange(pixels) * cells // pixels
    return np.where(dark[np.ix_(index, index)], 0, 255).astype(np.uint8)


# --- the plate face --------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TagFace:
    """The plate face as drawn, and where it lies in metres.

    ``image`` row 0 is the top of the plate, column 0 its left edge (seen from the front).
    Pixel counts are rounded, so the real extents are ``width`` and ``height`` (within half
    a pixel of ``face_size``) and the marker centre is ``marker_centre`` (within a pixel
    of ``0.75 size`` from the top and left edges).
    """

    image: Grey
    pixels_per_metre: float
    marker_centre: tuple[float, float]
    """Metres from the face's top-left corner, rightward and downward."""

    @property
    def width(self) -> float:
        return float(self.image.shape[1] / self.pixels_per_metre)

    @property
    def height(self) -> float:
        return float(self.image.shape[0] / self.pixels_per_metre)

    def corners_px(self) -> NDArray[np.float32]:
        """Outer corners of ``image`` in OpenCV pixel coordinates (pixel centres at integers).

        Order: top-left, top-right, bottom-right, bottom-left, matching ``corners_m``; with
        the projected ``corners_m`` they give ``cv2.getPerspectiveTransform`` its input.
        """
        right, bottom = self.image.shape[1] - 0.5, self.image.shape[0] - 0.5
        return np.array([(-0.5, -0.5), (right, -0.5), (right, bottom), (-0.5, bottom)], np.float32)

    def corners_m(self) -> NDArray[np.float32]:
        """The same corners in metres from the marker centre, as (rightward, upward)."""
        left, top = -self.marker_centre[0], self.marker_centre[1]
        right, bottom = left + self.width, top - self.height
        return np.array([(left, top), (right, top), (right, bottom), (left, bottom)], np.float32)


def tag_face(
    marker_id: int,
    payload: str,
    dictionary: str,
    pixels_per_metre: float,
    size: float,
    qr_version: int = QR_VERSION,
) -> TagFace:
    """Draw the plate face of the layout contract (no text) at ``pixels_per_metre``.

    ``qr_version`` draws a QR code of another version in the same square (``qr_image``),
    for the simulated camera's range experiments.

    Every edge is placed at its nominal position rounded to the nearest pixel and each code
    is ``size`` wide within half a pixel, so the drawing is within a pixel of the contract
    everywhere; ``TagFace`` reports where things really are. Raises ``TagPayloadError``
    for a bad marker id, dictionary or payload, ``ValueError`` if the density leaves fewer
    than one pixel per QR module.
    """

    def pixels(units_of_size: float) -> int:
        return round(units_of_size * size * pixels_per_metre)

    code, band, qr_left = pixels(1), pixels(QUIET_ZONE), pixels(1 + 2 * QUIET_ZONE)
    image = np.full((pixels(FACE_HEIGHT), pixels(FACE_WIDTH)), 255, np.uint8)
    image[band : band + code, band : band + code] = marker_image(marker_id, dictionary, code)
    image[band : band + code, qr_left : qr_left + code] = qr_image(payload, code, qr_version)
    centre = (band + code / 2) / pixels_per_metre
    return TagFace(image, pixels_per_metre, (centre, centre))


# --- printing --------------------------------------------------------------------------


@dataclass(frozen=True)
class TagArt:
    """Everything printed on one tag."""

    marker_id: int
    payload: str
    map_id: str
    links_to: str
    size: float = DEFAULT_SIZE
    dictionary: str = DEFAULT_DICTIONARY

    def caption(self) -> tuple[str, str, str]:
        """The three lines printed below the face."""
        return (
            self.map_id,
            f"marker {self.marker_id} ({self.size * 1000:g} mm)",
            f"to {self.links_to}",
        )


def render_tag_png(tag: TagArt, dpi: int = 300) -> bytes:
    """PNG of one tag at true size when printed at ``dpi`` (written to the PNG's pHYs).

    Each code measures ``tag.size`` within half a pixel. Raises as ``tag_face``.
    """
    buffer = io.BytesIO()
    _print_image(tag, dpi).save(buffer, "PNG", dpi=(dpi, dpi))
    return buffer.getvalue()


def render_tag_pdf(tags: Sequence[TagArt], dpi: int = 300) -> bytes:
    """PDF of ``tags`` at true size on A4 portrait pages, as many per page as fit.

    The page is exactly A4 (its MediaBox); the page images are ``dpi`` dots per inch to
    within half a dot across the page, so codes keep ``size`` within about half a pixel.
    Raises ``TagPayloadError`` for no tags, a tag larger than a page, or as ``tag_face``.
    """
    pages = tag_sheets(tags, dpi)
    # Per-axis resolution that makes the MediaBox A4 exactly, not A4 rounded to pixels.
    resolution = tuple(
        pixels * INCH / metres for pixels, metres in zip(pages[0].size, A4, strict=True)
    )
    buffer = io.BytesIO()
    pages[0].save(buffer, "PDF", save_all=True, append_images=pages[1:], dpi=resolution)
    return buffer.getvalue()


def tag_sheets(tags: Sequence[TagArt], dpi: int) -> list[Image.Image]:
    """A4 pages (bilevel images at ``dpi``) with ``tags`` packed in rows, in order.

    A tag too wide for the page is turned a quarter turn. Raises ``TagPayloadError`` for no
    tags or a tag that fits neither way.
    """
    if not tags:
        raise TagPayloadError("no tags to print")
    sheet = _Sheet(dpi / INCH)
    for tag in tags:
        sheet.place(_print_image(tag, dpi))
    sheet.finish_page()
    return sheet.pages


class _Sheet:
    """Shelf packing on A4 pages: left to right in rows, rows top to bottom."""

    def __init__(self, pixels_per_metre: float) -> None:
        self.page_size = (round(A4[0] * pixels_per_metre), round(A4[1] * pixels_per_metre))
        self.margin = round(PAGE_MARGIN * pixels_per_metre)
        self.pages: list[Image.Image] = []
        self.x = self.y = self.row_height = 0

    def place(self, image: Image.Image) -> None:
        image = self._oriented(image)
        if self.pages and self.x + image.width > self.page_size[0] - self.margin:
            self.x, self.y, self.row_height = self.margin, self.y + self.row_height, 0
        if not self.pages or self.y + image.height > self.page_size[1] - self.margin:
            self.finish_page()
            self.pages.append(Image.new("L", self.page_size, 255))
            self.x = self.y = self.margin
            self.row_height = 0
        self.pages[-1].paste(image, (self.x, self.y))
        self.x += image.width
        self.row_height = max(self.row_height, image.height)

    def finish_page(self) -> None:
        """Make the last page bilevel (kept one page at a time, so grey pages do not pile up):
        bilevel pages go into the PDF losslessly (CCITT G4) where grey would become JPEG."""
        if self.pages and self.pages[-1].mode != "1":
            self.pages[-1] = self.pages[-1].convert("1", dither=Image.Dither.NONE)

    def _oriented(self, image: Image.Image) -> Image.Image:
        usable = [side - 2 * self.margin for side in self.page_size]
        if image.width > usable[0]:
            image = image.transpose(Image.Transpose.ROTATE_90)
        if image.width > usable[0] or image.height > usable[1]:
            raise TagPayloadError("tag is too large for an A4 page at true size")
        return image


def print_memory(sizes: Sequence[float], dpi: int = 300) -> int:
    """Estimate the bytes that printing tags of ``sizes`` holds at its peak: the drawing
    of the largest tag (a few bytes per pixel), and the A4 pages of a sheet (a byte each).

    Raises TagPayloadError for a size out of ``MIN_SIZE`` to ``MAX_SIZE``, which no print
    takes."""
    for size in sizes:
        _check_size(size)
    pixels_per_metre = dpi / INCH
    caption = sum(TEXT_POINTS) * 1.4 * INCH / 72
    areas = [
        (FACE_WIDTH * size + 2 * PRINT_MARGIN) * (FACE_HEIGHT * size + caption + 2 * PRINT_MARGIN)
        for size in sizes
    ]
    page = A4[0] * A4[1]
    pages = math.ceil(sum(areas) / page) + 1
    return round((4 * max(areas, default=0) + pages * page) * pixels_per_metre**2)


def _check_size(size: float) -> None:
    if not MIN_SIZE <= size <= MAX_SIZE:
        raise TagPayloadError(f"a tag's size must be {MIN_SIZE} to {MAX_SIZE} m, not {size}")


def _print_image(tag: TagArt, dpi: int) -> Image.Image:
    """Grey image of one printed tag: margin, crop marks, face, and caption below it.

    Raises TagPayloadError for a size out of ``MIN_SIZE`` to ``MAX_SIZE``."""
    _check_size(tag.size)
    pixels_per_metre = dpi / INCH
    face = tag_face(tag.marker_id, tag.payload, tag.dictionary, pixels_per_metre, tag.size)
    margin = round(PRINT_MARGIN * pixels_per_metre)
    face_height, face_width = face.image.shape
    lines = list(_caption_lines(tag, dpi, face_width))
    text_height = sum(line_height for _, _, line_height in lines)
    canvas = Image.new("L", (face_width + 2 * margin, face_height + text_height + 2 * margin), 255)
    canvas.paste(Image.fromarray(face.image), (margin, margin))
    # The caption lines up with the marker's left edge and starts below the white band.
    x = margin + round(QUIET_ZONE * tag.size * pixels_per_metre)
    y = margin + face_height
    draw = ImageDraw.Draw(canvas)
    for text, font, line_height in lines:
        draw.text((x, y), text, fill=0, font=font)
        y += line_height
    _draw_crop_marks(draw, canvas.size, pixels_per_metre)
    return canvas


Font = ImageFont.FreeTypeFont | ImageFont.ImageFont


def _caption_lines(tag: TagArt, dpi: int, face_width: int) -> Iterator[tuple[str, Font, int]]:
    """Each caption line with its font and line height, shrunk to fit between the bands."""
    band = round(QUIET_ZONE * tag.size * dpi / INCH)
    room = face_width - 2 * band
    for text, points in zip(tag.caption(), TEXT_POINTS, strict=True):
        pixels = points * dpi / 72
        width = _text_width(text, pixels)
        if width > room:
            pixels *= room / width
        yield text, ImageFont.load_default(size=pixels), math.ceil(pixels * 1.4)


def _text_width(text: str, pixels: float) -> float:
    left, _, right, _ = ImageFont.load_default(size=pixels).getbbox(text)
    return float(right - left)


def _draw_crop_marks(draw: ImageDraw.ImageDraw, size: tuple[int, int], ppm: float) -> None:
    """Short L-shaped marks at the four corners, showing where to cut without a frame line.

    A full frame would put a long dark edge near the codes, which detectors could try as
    a candidate; corner marks keep the margin clear.
    """
    arm, thick = round(CROP_MARK * ppm), max(1, round(0.0002 * ppm))
    width, height = size
    for left, edge_x in ((0, 0), (width - arm, width - thick)):
        for top, edge_y in ((0, 0), (height - arm, height - thick)):
            draw.rectangle([left, edge_y, left + arm - 1, edge_y + thick - 1], fill=0)
            draw.rectangle([edge_x, top, edge_x + thick - 1, top + arm - 1], fill=0)
