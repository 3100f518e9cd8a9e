"""Tag artwork: printed tags at true size, and the face the simulated camera sees.

Pure domain, no database. Codes are read back with the detectors robots use:
``cv2.aruco.ArucoDetector`` for the marker and zxing-cpp for the QR code.
"""

from __future__ import annotations

import io
import math
import re
from typing import Any

import cv2
import numpy as np
import pytest
import zxingcpp
from numpy.typing import NDArray
from PIL import Image

from maps.domain.tagart import (
    A4,
    QR_MODULES,
    QUIET_ZONE,
    TagArt,
    TagFace,
    aruco_dictionary,
    face_size,
    marker_image,
    qr_centre,
    qr_image,
    qr_offset,
    render_tag_pdf,
    render_tag_png,
    tag_face,
    tag_sheets,
)
from maps.exceptions import TagPayloadError

PAYLOAD = "http://127.0.0.1:8000, 56037, boccioni_1, CorridorA"
DICTIONARY = "DICT_APRILTAG_36h11"
POINTS_PER_MM = 72 / 25.4

# The simulated camera of docs/design.md, drawn at 4x and reduced with INTER_AREA (FACTS.md).
CAMERA_SIZE = (640, 480)
FOCAL = 525.0
OVERSAMPLE = 4


def make_tag(**kwargs: Any) -> TagArt:
    kwargs.setdefault("marker_id", 17)
    kwargs.setdefault("payload", PAYLOAD)
    kwargs.setdefault("map_id", "boccioni_1/CorridorA")
    kwargs.setdefault("links_to", "boccioni_1/CorridorB")
    return TagArt(**kwargs)


def detect_markers(grey: NDArray[np.uint8]) -> dict[int, NDArray[np.float32]]:
    """Marker id -> its four corners (ArUco order) as found by the robots' detector."""
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(aruco_dictionary(DICTIONARY), parameters)
    corners, ids, _ = detector.detectMarkers(grey)
    return {} if ids is None else {int(i): c[0] for i, c in zip(ids.ravel(), corners, strict=True)}


def read_qr(grey: NDArray[np.uint8]) -> list[zxingcpp.Barcode]:
    return zxingcpp.read_barcodes(grey)


def qr_centre_px(barcode: zxingcpp.Barcode) -> NDArray[np.float64]:
    """Where the diagonals of the decoded symbol cross: its centre, also in perspective."""
    position = barcode.position
    corners = [position.top_left, position.top_right, position.bottom_right, position.bottom_left]
    (a, b, c, d) = [np.array([point.x, point.y, 1.0]) for point in corners]
    crossing = np.cross(np.cross(a, c), np.cross(b, d))
    return crossing[:2] / crossing[2]


def png_pixels(png: bytes) -> tuple[NDArray[np.uint8], float]:
    """Grey pixels of a PNG and its pixels per metre from pHYs."""
    image = Image.open(io.BytesIO(png))
    return np.asarray(image.convert("L")), image.info["dpi"][0] / 0.0254


def marker_width_px(grey: NDArray[np.uint8], corners: NDArray[np.float32]) -> int:
    """Width in whole pixels of the marker's black square around the detected ``corners``."""
    (x0, y0), (x1, y1) = corners.min(axis=0).astype(int) - 5, corners.max(axis=0).astype(int) + 6
    dark_columns = np.flatnonzero((grey[y0:y1, x0:x1] < 128).any(axis=0))
    return int(dark_columns[-1] - dark_columns[0] + 1)


def camera_view(face: TagFace, distance: float, turn: float) -> tuple[NDArray[Any], Any]:
    """What the simulated camera sees of ``face``, its centre straight ahead at ``distance``
    and the plate turned ``turn`` radians about its vertical axis, as the simulator draws it:
    project ``corners_m``, warp ``corners_px`` onto them at 4x, reduce with INTER_AREA.

    Returns the 640x480 grey image and a function projecting plate points (rightward, upward
    metres from the marker centre) to its pixels.
    """
    right = np.array([math.cos(turn), 0.0, math.sin(turn)])  # camera: x right, y down, z ahead
    up = np.array([0.0, -1.0, 0.0])
    face_centre = face.corners_m().mean(axis=0)
    marker = np.array([0.0, 0.0, distance]) - right * face_centre[0] - up * face_centre[1]
    principal = (np.array(CAMERA_SIZE) - 1) / 2

    def project(plate: NDArray[np.float32], scale: float = 1.0) -> NDArray[np.float32]:
        points = marker + np.outer(plate[:, 0], right) + np.outer(plate[:, 1], up)
        pixels = points[:, :2] / points[:, 2:] * FOCAL + principal
        return ((pixels + 0.5) * scale - 0.5).astype(np.float32)

    big_size = (CAMERA_SIZE[0] * OVERSAMPLE, CAMERA_SIZE[1] * OVERSAMPLE)
    homography = cv2.getPerspectiveTransform(face.corners_px(), project(face.corners_m(), 4))
    big = cv2.warpPerspective(face.image, homography, big_size, borderValue=(120,))
    return cv2.resize(big, CAMERA_SIZE, interpolation=cv2.INTER_AREA), project


def pdf_pages(pdf: bytes) -> tuple[int, list[list[float]], list[int]]:
    """Page count, every page's MediaBox and every image's pixel width, read from the bytes."""
    count = len(re.findall(rb"/Type\s*/Page\b", pdf))
    boxes = [
        [float(number) for number in box.split()]
        for box in re.findall(rb"/MediaBox\s*\[([^\]]*)\]", pdf)
    ]
    widths = [int(width) for width in re.findall(rb"/Width\s+(\d+)", pdf)]
    return count, boxes, widths


# --- round trips ---------------------------------------------------------------------


def test_a_printed_tag_reads_back_its_marker_id_and_payload() -> None:
    grey, _ = png_pixels(render_tag_png(make_tag()))

    assert list(detect_markers(grey)) == [17]
    assert [barcode.text for barcode in read_qr(grey)] == [PAYLOAD]


@pytest.mark.parametrize("turn_degrees", [0, 30, -30])
def test_a_camera_at_40_cm_reads_back_the_marker_id_and_payload(turn_degrees: int) -> None:
    face = tag_face(23, PAYLOAD, DICTIONARY, QR_MODULES * 24 / 0.06, 0.06)
    view, _ = camera_view(face, 0.4, math.radians(turn_degrees))

    assert list(detect_markers(view)) == [23]
    assert [barcode.text for barcode in read_qr(view)] == [PAYLOAD]


def test_the_camera_finds_the_qr_code_where_qr_offset_puts_it() -> None:
    face = tag_face(5, PAYLOAD, DICTIONARY, 12000.0, 0.06)
    view, project = camera_view(face, 0.4, math.radians(25))

    (found,) = read_qr(view)
    expected_qr = project(np.array([[qr_offset(0.06), 0.0]], np.float32))[0]
    # zxing-cpp places a symbol's corners to about a pixel; ArUco's refined corners, a quarter.
    assert np.linalg.norm(qr_centre_px(found) - expected_qr) < 1.5
    # ArUco corner order, as solvePnP's IPPE square wants it (FACTS.md).
    half = 0.03
    marker = np.array([(-half, half), (half, half), (half, -half), (-half, -half)], np.float32)
    assert np.linalg.norm(detect_markers(view)[5] - project(marker), axis=1).max() < 1.0


# --- the face and its geometry -------------------------------------------------------


def dark_box(grey: NDArray[np.uint8], first_column: int, last_column: int) -> NDArray[np.int64]:
    """Edges (left, top, right, bottom) in pixels of the dark pixels between two columns.

    Exact for both codes: the marker's border is solid, and the QR code's three finder
    patterns reach its left, right, top and bottom edges.
    """
    rows, columns = np.nonzero(grey[:, first_column:last_column] < 128)
    return np.array(
        [columns.min() + first_column, rows.min(), columns.max() + first_column + 1, rows.max() + 1]
    )


@pytest.mark.parametrize("pixels_per_metre", [7777.0, 10000.0, QR_MODULES * 2 / 0.06])
def test_the_face_puts_marker_left_and_qr_right_as_the_layout_contract_says(
    pixels_per_metre: float,
) -> None:
    face = tag_face(3, PAYLOAD, DICTIONARY, pixels_per_metre, 0.06)
    half = face.image.shape[1] // 2

    marker = dark_box(face.image, 0, half) / pixels_per_metre
    qr = dark_box(face.image, half, face.image.shape[1]) / pixels_per_metre
    pixel = 1 / pixels_per_metre
    for left, top, right, bottom in (marker, qr):
        assert (right - left, bottom - top) == pytest.approx((0.06, 0.06), abs=pixel / 2)
    marker_centre = (marker[:2] + marker[2:]) / 2
    assert marker_centre == pytest.approx(face.marker_centre, abs=1e-9)
    assert marker_centre == pytest.approx((0.045, 0.045), abs=pixel)
    assert (qr[:2] + qr[2:]) / 2 - marker_centre == pytest.approx((qr_offset(0.06), 0), abs=pixel)


def test_the_face_measures_its_nominal_size_and_its_corners_say_so() -> None:
    face = tag_face(3, PAYLOAD, DICTIONARY, 7777.0, 0.06)

    assert (face.width, face.height) == pytest.approx(face_size(0.06), abs=0.5 / 7777)
    assert face_size(0.06) == pytest.approx((0.165, 0.09))
    left, top = face.corners_m()[0]
    right, bottom = face.corners_m()[2]
    assert (right - left, top - bottom) == pytest.approx((face.width, face.height))
    assert (left, top, bottom) == pytest.approx((-0.045, 0.045, -0.045), abs=1 / 7777)


def test_the_qr_quiet_zone_is_at_least_the_four_modules_the_standard_asks_for() -> None:
    assert QUIET_ZONE * QR_MODULES >= 4
    assert qr_offset(0.06) == pytest.approx(0.075)


@pytest.mark.parametrize(
    ("yaw", "expected"), [(0.0, (1.0, 2.075)), (math.pi / 2, (0.925, 2.0)), (math.pi, (1.0, 1.925))]
)
def test_the_qr_sits_to_the_right_of_the_marker_seen_from_the_front(
    yaw: float, expected: tuple[float, float]
) -> None:
    # A tag facing +x is seen by someone looking towards -x, whose right is +y.
    assert qr_centre(1.0, 2.0, yaw, 0.06) == pytest.approx(expected)


def test_marker_image_has_its_black_border_and_no_white_margin() -> None:
    image = marker_image(17, DICTIONARY, 80)  # 36h11: 6 bits + 2 border cells = 10 px a cell

    assert image.shape == (80, 80)
    assert image.dtype == np.uint8
    assert set(np.unique(image)) <= {0, 255}
    border = np.concatenate([image[:10].ravel(), image[-10:].ravel(), image[:, :10].ravel()])
    assert (border == 0).all()
    assert list(detect_markers(np.pad(image, 20, constant_values=255))) == [17]


def test_qr_image_is_the_bare_version_3_module_grid() -> None:
    image = qr_image(PAYLOAD, QR_MODULES * 4)

    assert image.shape == (116, 116)
    modules = image[::4, ::4]
    assert (image == np.kron(modules, np.ones((4, 4), np.uint8))).all()  # exact 4 px modules
    assert (modules[0, :7] == 0).all()  # the finder pattern touches the edge: no quiet zone
    padded = np.pad(image, 16, constant_values=255)
    assert [barcode.text for barcode in read_qr(padded)] == [PAYLOAD]
    assert read_qr(padded)[0].symbology_identifier == "]Q1"


def test_qr_image_raises_for_a_payload_too_long_for_version_3_l() -> None:
    with pytest.raises(TagPayloadError, match="53"):
        qr_image("x" * 54, 116)


def test_an_unknown_dictionary_raises() -> None:
    with pytest.raises(TagPayloadError, match="dictionary"):
        marker_image(1, "DICT_NOPE", 80)


def test_a_marker_id_outside_the_dictionary_raises() -> None:
    with pytest.raises(TagPayloadError, match="587"):  # 36h11 has ids 0..586
        marker_image(587, DICTIONARY, 80)


# --- true physical size ----------------------------------------------------------------


def test_a_marker_printed_at_300_dpi_measures_6_cm() -> None:
    grey, pixels_per_metre = png_pixels(render_tag_png(make_tag(), dpi=300))

    assert pixels_per_metre == pytest.approx(300 / 0.0254, rel=1e-5)  # pHYs says 300 dpi
    width = marker_width_px(grey, detect_markers(grey)[17]) / pixels_per_metre
    assert width == pytest.approx(0.06, abs=0.5 / pixels_per_metre)


def test_a_9_cm_marker_at_200_dpi_measures_9_cm() -> None:
    grey, pixels_per_metre = png_pixels(render_tag_png(make_tag(size=0.09), dpi=200))

    width = marker_width_px(grey, detect_markers(grey)[17]) / pixels_per_metre
    assert width == pytest.approx(0.09, abs=0.5 / pixels_per_metre)


def test_a_pdf_of_ten_tags_has_five_a4_pages() -> None:
    tags = [make_tag(marker_id=marker_id) for marker_id in range(10)]

    count, boxes, _ = pdf_pages(render_tag_pdf(tags))

    # A 6 cm tag prints 175 x 115 mm: one across and two down an A4 page.
    assert count == 5
    a4_points = [0, 0, A4[0] * 1000 * POINTS_PER_MM, A4[1] * 1000 * POINTS_PER_MM]
    assert all(box == pytest.approx(a4_points, abs=1e-6) for box in boxes)
    assert len(boxes) == 5


def test_a_pdf_of_one_tag_is_one_a4_page() -> None:
    count, boxes, _ = pdf_pages(render_tag_pdf([make_tag()]))

    assert count == 1
    assert boxes[0][2:] == pytest.approx([595.2756, 841.8898], abs=1e-4)


def test_a_marker_in_the_pdf_measures_6_cm() -> None:
    _, boxes, widths = pdf_pages(render_tag_pdf([make_tag()], dpi=300))
    (page,) = tag_sheets([make_tag()], dpi=300)
    grey = np.asarray(page.convert("L"))

    assert widths == [page.width]
    millimetres_per_pixel = boxes[0][2] / page.width / POINTS_PER_MM
    width = marker_width_px(grey, detect_markers(grey)[17]) * millimetres_per_pixel
    assert width == pytest.approx(60.0, abs=0.5 * 25.4 / 300)


def test_every_tag_on_a_sheet_reads_back() -> None:
    tags = [
        make_tag(marker_id=4, payload=PAYLOAD),
        make_tag(marker_id=9, payload="http://h, , b, m"),
    ]

    (page,) = tag_sheets(tags, dpi=150)
    grey = np.asarray(page.convert("L"))

    assert sorted(detect_markers(grey)) == [4, 9]
    assert sorted(barcode.text for barcode in read_qr(grey)) == sorted(tag.payload for tag in tags)


def test_a_tag_too_wide_for_the_page_is_turned_a_quarter_turn() -> None:
    (page,) = tag_sheets([make_tag(size=0.09)], dpi=100)
    grey = np.asarray(page.convert("L"))

    top_left, top_right = detect_markers(grey)[17][:2]  # ArUco order: the marker's top edge
    # ...runs up the page: the tag was turned a quarter turn anticlockwise.
    assert abs(top_right[0] - top_left[0]) < 2
    assert top_left[1] - top_right[1] > 300


def test_a_tag_larger_than_a_page_raises() -> None:
    with pytest.raises(TagPayloadError, match="A4"):
        render_tag_pdf([make_tag(size=0.2)])


def test_a_pdf_of_no_tags_raises() -> None:
    with pytest.raises(TagPayloadError, match="no tags"):
        render_tag_pdf([])
