"""Environmental tags found in camera pixels: the marker's pose and the QR code's payload.

Nothing here reads ground truth; the input is an image and the camera's calibration.

Frames
======

- Camera optical frame (OpenCV): x right, y down, z forward along the optical axis.
- Marker frame (ArUco): origin at the marker centre, x to the marker's right, y up,
  z out of the printed face (the tag's outward normal, docs/design.md's yaw direction).
- Robot base frame (REP 103): x forward, y left, z up, origin on the floor under the
  robot's centre. The camera looks straight ahead along base x, level, its optical centre
  ``mount_x`` ahead of the origin and ``mount_height`` above the floor.

A detection gives the camera -> marker transform (``rotation`` and ``translation``: a
point ``p`` in marker coordinates is ``rotation @ p + translation`` in the camera frame)
and, through ``CameraModel.base_from_camera``, the marker's planar pose in the base frame:
``base_x, base_y`` and ``relative_yaw``, the direction of the tag's outward normal seen
from the robot (``pi`` when the tag faces the robot head-on).

Pose
====

Corners: ArUco's, moved onto lines fitted to the marker's four outer edges
(``refine_corners``), several times more accurate than ArUco's own refinement.

Two-solution ambiguity: a small square seen nearly head-on has two poses that explain its
corners almost equally well (IPPE square returns both); they differ in the marker's yaw
and tilt, by tens of degrees at a metre and more. Two remedies, in order:

1. Upright fit (``upright=True``, the default): the robot's camera is level and tags hang
   on vertical walls, so the marker can only turn about the camera's vertical axis. The
   pose is refitted with that constraint (yaw plus translation, four unknowns for eight
   corner coordinates) from each IPPE solution and from their mean; the constraint
   removes most of the ambiguity (over 56 rendered views at 1.2 to 1.6 m, yaw error p90
   1.6 and worst 3.2 degrees, against 2.3 and 37 with IPPE alone).
2. Over time: when the two best candidates still explain the corners about equally well
   (reprojection errors within ``AMBIGUITY_RATIO``), the detector keeps, per marker id,
   the one whose normal is nearer the normal it chose last time for that marker, if it
   saw the marker within ``memory_frames`` frames; otherwise the one with the smaller
   error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
import zxingcpp
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.messages import PinholeCalibration
from cloudnav_core.se2 import Pose, angle_between
from maps.domain.tagart import DEFAULT_DICTIONARY, DEFAULT_SIZE, QUIET_ZONE, aruco_dictionary
from maps.domain.tagart import qr_offset as tag_qr_offset
from maps.domain.tagpayload import TagPayload, parse_payload
from maps.exceptions import TagPayloadError

Image = NDArray[np.uint8]
Matrix = NDArray[np.float64]
Solution = tuple[Matrix, Matrix, float]
"""A marker pose: rotation, translation (camera frame) and RMS reprojection error (px)."""

AMBIGUITY_RATIO = 3.0
"""Two poses whose reprojection errors are within this factor are both plausible."""

_QR_FORMATS = zxingcpp.BarcodeFormats(zxingcpp.BarcodeFormat.QRCode)
_QR_MARGIN = QUIET_ZONE
"""How much beyond the QR square the crop reaches, in units of the tag size: the quiet
zone, which the decoder needs to see."""


def pinhole_calibration(model: CameraModel) -> PinholeCalibration:
    """The calibration a camera driver publishes for ``model`` (its ``CameraInfo`` but
    the header): size, K, no distortion (``plumb_bob``, zeros), R the identity and P
    ``[K | 0]`` (a monocular camera)."""
    fx, fy, cx, cy = model.fx, model.fy, model.cx, model.cy
    return {
        "height": model.height,
        "width": model.width,
        "distortion_model": "plumb_bob",
        "D": [0.0] * 5,
        "K": [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "P": [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    }


@dataclass(frozen=True)
class TagDetection:
    """One marker found in an image, with its pose and, when read, its QR payload."""

    marker_id: int
    corners: NDArray[np.float32] = field(repr=False)
    """Image corners, ArUco order: top-left, top-right, bottom-right, bottom-left."""
    size: float
    rotation: Matrix = field(repr=False)
    translation: Matrix = field(repr=False)
    reprojection_error: float
    base_x: float
    base_y: float
    relative_yaw: float
    ambiguity: float = 0.0
    """Radians between ``relative_yaw`` and that of another pose explaining the corners
    about as well (within ``AMBIGUITY_RATIO``); 0 when the pose stands alone. The two are
    mirror images about the line of sight: expect one of them to be right."""
    qr_text: str | None = None
    payload: TagPayload | None = None

    @property
    def distance(self) -> float:
        """Metres from the camera's optical centre to the marker centre."""
        return float(np.linalg.norm(self.translation))

    @property
    def bearing(self) -> float:
        """Direction of the marker centre from the robot's centre, radians, left positive."""
        return math.atan2(self.base_y, self.base_x)

    @property
    def view_angle(self) -> float:
        """Angle between the tag's normal and the line from the tag to the camera, radians."""
        to_camera = -self.translation / max(self.distance, 1e-9)
        return float(math.acos(np.clip(self.rotation[:, 2] @ to_camera, -1.0, 1.0)))

    def base_pose(self) -> Pose:
        """The marker's ``(x, y, yaw)`` on the floor plane of the robot base frame."""
        return self.base_x, self.base_y, self.relative_yaw

    def camera_to_marker(self) -> Matrix:
        """The 4x4 homogeneous transform taking marker coordinates to camera coordinates."""
        transform = np.eye(4)
        transform[:3, :3], transform[:3, 3] = self.rotation, self.translation
        return transform


class TagDetector:
    """Finds markers of ``dictionary`` and reads the QR code beside each one.

    ``sizes`` gives the physical size of particular marker ids; others are ``default_size``.
    Keep one detector per camera: it remembers each marker's last pose to resolve the
    two-solution ambiguity over ``memory_frames`` frames.
    """

    def __init__(
        self,
        camera: CameraModel | None = None,
        *,
        dictionary: str = DEFAULT_DICTIONARY,
        default_size: float = DEFAULT_SIZE,
        sizes: Mapping[int, float] | None = None,
        read_qr: bool = True,
        upright: bool = True,
        memory_frames: int = 15,
    ) -> None:
        self.camera = camera or CameraModel()
        self.default_size = default_size
        self.sizes = dict(sizes or {})
        self.read_qr = read_qr
        self.upright = upright
        self.memory_frames = memory_frames
        vocabulary = aruco_dictionary(dictionary)
        self._aruco = cv2.aruco.ArucoDetector(vocabulary, _aruco_parameters())
        self._cells = int(vocabulary.markerSize) + 2  # one border cell on each side
        self._matrix = self.camera.matrix()
        self._previous: dict[int, tuple[int, Matrix]] = {}  # id -> (frame, chosen normal)
        self._frame = 0

    def detect(self, image: Image) -> list[TagDetection]:
        """Markers in ``image`` (grey or BGR uint8) with their poses and QR payloads.

        A marker whose pose cannot be computed is left out. ``payload`` is None when the QR
        code is not read or does not parse as a tag payload (``qr_text`` then holds the
        text, if any).
        """
        grey = (
            image
            if image.ndim == 2
            else np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
        )
        self._frame += 1
        corners, ids, _ = self._aruco.detectMarkers(grey)
        if ids is None:
            return []
        levels = grey.astype(np.float32)
        found = [
            self._measure(
                int(i), refine_corners(levels, np.asarray(c, np.float32).reshape(4, 2), self._cells)
            )
            for i, c in zip(ids.ravel(), corners, strict=True)
        ]
        detections = [d for d in found if d is not None]
        return self._with_qr(grey, detections) if self.read_qr else detections

    # --- marker pose -------------------------------------------------------------------

    def _measure(self, marker_id: int, corners: NDArray[np.float32]) -> TagDetection | None:
        size = self.sizes.get(marker_id, self.default_size)
        solutions = _ippe_solutions(corners, size, self._matrix)
        if solutions and self.upright:
            solutions = _upright_solutions(solutions, corners, size, self._matrix)
        if not solutions:
            return None
        rotation, translation, error = self._choose(marker_id, solutions)
        centre = self.camera.base_from_camera(translation)
        yaw = self._relative_yaw(rotation)
        rival = _ambiguous(solutions)
        return TagDetection(
            marker_id=marker_id,
            corners=corners,
            size=size,
            rotation=rotation,
            translation=translation,
            reprojection_error=error,
            base_x=float(centre[0]),
            base_y=float(centre[1]),
            relative_yaw=yaw,
            ambiguity=0.0 if rival is None else angle_between(yaw, self._relative_yaw(rival[0])),
        )

    def _relative_yaw(self, rotation: Matrix) -> float:
        """Direction of the marker's normal in the base frame, radians."""
        normal = self.camera.base_direction(rotation[:, 2])
        return math.atan2(normal[1], normal[0])

    def _choose(self, marker_id: int, solutions: list[Solution]) -> Solution:
        """The best solution, or, when the runner-up is about as good, the one whose normal
        is nearer the marker's last chosen normal (if seen lately). ``solutions`` is
        sorted by reprojection error."""
        chosen = solutions[0]
        previous = self._previous.get(marker_id)
        recent = previous is not None and self._frame - previous[0] <= self.memory_frames
        if recent and _ambiguous(solutions) is not None:
            last_normal = previous[1]  # type: ignore[index]
            chosen = max(solutions[:2], key=lambda s: float(s[0][:, 2] @ last_normal))
        self._previous[marker_id] = (self._frame, chosen[0][:, 2])
        return chosen

    # --- QR codes ----------------------------------------------------------------------

    def _with_qr(self, grey: Image, detections: list[TagDetection]) -> list[TagDetection]:
        """``detections`` with the QR text beside each marker: first from a crop where the
        layout puts the code, then, for any still unread, from the whole frame."""
        texts = {d.marker_id: _read_one(self._qr_crop(grey, d)) for d in detections}
        if any(text is None for text in texts.values()):
            whole = zxingcpp.read_barcodes(grey, formats=_QR_FORMATS)
            for detection in detections:
                if texts[detection.marker_id] is None:
                    texts[detection.marker_id] = self._nearest_qr(detection, whole)
        return [_with_text(d, texts[d.marker_id]) for d in detections]

    def _qr_square(self, detection: TagDetection, margin: float) -> NDArray[np.float32]:
        """Image points of the QR square beside ``detection``, grown by ``margin`` (units of
        size) on every side: right of the marker by the layout's ``qr_offset``."""
        size = detection.size
        half = size * (0.5 + margin)
        centre = tag_qr_offset(size)
        square = np.array(
            [
                [centre + dx * half, dy * half, 0.0]
                for dx, dy in ((-1, 1), (1, 1), (1, -1), (-1, -1))
            ]
        )
        rvec, _ = cv2.Rodrigues(detection.rotation)
        points, _ = cv2.projectPoints(square, rvec, detection.translation, self._matrix, None)
        return points.reshape(4, 2).astype(np.float32)

    def _qr_crop(self, grey: Image, detection: TagDetection) -> Image | None:
        """The part of ``grey`` where ``detection``'s QR code must be, or None if off-image."""
        points = self._qr_square(detection, _QR_MARGIN)
        x0, y0 = np.floor(points.min(axis=0)).astype(int)
        x1, y1 = np.ceil(points.max(axis=0)).astype(int) + 1
        height, width = grey.shape
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
        if x1 - x0 < 8 or y1 - y0 < 8:
            return None
        return grey[y0:y1, x0:x1]

    def _nearest_qr(self, detection: TagDetection, codes: Sequence[zxingcpp.Barcode]) -> str | None:
        """Text of the code in ``codes`` whose centre is nearest where ``detection``'s QR
        centre projects, if within one QR width of it."""
        square = self._qr_square(detection, 0.0)
        expected, reach = square.mean(axis=0), float(np.linalg.norm(square[0] - square[1]))
        best: tuple[float, str] | None = None
        for code in codes:
            offset = float(np.linalg.norm(_code_centre(code) - expected))
            if offset <= reach and (best is None or offset < best[0]):
                best = (offset, code.text)
        return None if best is None else best[1]


def _aruco_parameters() -> cv2.aruco.DetectorParameters:
    """Detector parameters: sub-pixel corners, for pose accuracy at a few pixels a cell."""
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return parameters


def marker_object_points(size: float) -> NDArray[np.float32]:
    """Marker corners in the marker frame, in ArUco's (and IPPE square's) order:
    top-left, top-right, bottom-right, bottom-left, seen from the front."""
    h = size / 2
    return np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], np.float32)


def refine_corners(
    grey: NDArray[np.float32], corners: NDArray[np.float32], cells: int
) -> NDArray[np.float32]:
    """Marker corners moved to the intersections of lines fitted to its four outer edges.

    ``cells`` is the marker's width in cells, border included. At points along each edge,
    a light profile across it locates the edge at the centroid of its rising slope (from
    black border to white quiet zone) near where it crosses halfway; ArUco's own corner
    refinement is pulled by the cells inside (up to a pixel at a metre, enough to turn
    the pose by tens of degrees). Two passes: the second samples around the first's
    edges. The detector's corners are kept when an edge cannot
    be fitted or a corner would move by more than a cell.
    """
    refined = corners.astype(np.float64)
    for _ in range(2):
        moved = _edge_corners(grey, refined, cells)
        if moved is None:
            break
        refined = moved
    sides = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1) / cells
    if np.abs(refined - corners).max() > sides.min():
        return corners
    return refined.astype(np.float32)


def _edge_corners(grey: NDArray[np.float32], corners: Matrix, cells: int) -> Matrix | None:
    """One pass of ``refine_corners``; None when an edge or a corner cannot be found."""
    sides = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1) / cells
    # Across edge i the cells are as wide as along its two neighbouring edges.
    across = (np.roll(sides, 1) + np.roll(sides, -1)) / 2
    lines = [_edge_line(grey, corners, index, across[index]) for index in range(4)]
    if any(line is None for line in lines):
        return None
    found = np.array([_intersection(lines[i - 1], lines[i]) for i in range(4)])  # type: ignore[arg-type]
    return found if np.isfinite(found).all() else None


Line = tuple[NDArray[np.float64], NDArray[np.float64]]
"""A point on the line and its unit direction."""

_EDGE_SAMPLES = 12
_PROFILE_SAMPLES = 25


def _edge_line(grey: NDArray[np.float32], corners: Matrix, index: int, cell: float) -> Line | None:
    """The line through the halfway crossings across the edge from corner ``index`` to
    the next, sampled over its middle 60 % (the corners themselves are blurred)."""
    start, end = corners[index], corners[(index + 1) % 4]
    along = end - start
    outward = np.array([along[1], -along[0]]) / max(float(np.linalg.norm(along)), 1e-9)
    if outward @ (corners.mean(axis=0) - start) > 0:
        outward = -outward
    # A cell either way: inside reaches the border's inner edge at most, outside stays on
    # the white band (two cells wide).
    offsets = np.linspace(-cell, cell, _PROFILE_SAMPLES)
    bases = start + np.linspace(0.2, 0.8, _EDGE_SAMPLES)[:, None] * along
    points = bases[:, None, :] + offsets[None, :, None] * outward
    maps = points.astype(np.float32)
    profiles = np.asarray(
        cv2.remap(grey, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR), dtype=np.float32
    )
    crossings = _gradient_centroids(profiles, offsets, _halfway_crossings(profiles, offsets))
    valid = np.isfinite(crossings)
    if valid.sum() < _EDGE_SAMPLES // 2:
        return None
    return _fit_line(bases[valid] + crossings[valid, None] * outward)


def _halfway_crossings(profiles: NDArray[np.float32], offsets: Matrix) -> Matrix:
    """Per profile (inside to outside), the offset where it last rises through halfway
    between its darkest and brightest samples: the border's outer edge, even when the
    profile starts on a white cell inside the border. NaN without contrast."""
    low, high = profiles.min(axis=1), profiles.max(axis=1)
    middle = ((low + high) / 2)[:, None]
    rising = (profiles[:, :-1] < middle) & (profiles[:, 1:] >= middle)
    last = rising.shape[1] - 1 - np.argmax(rising[:, ::-1], axis=1)
    rows = np.arange(profiles.shape[0])
    before, after = profiles[rows, last], profiles[rows, last + 1]
    fraction = (middle[:, 0] - before) / np.maximum(after - before, 1e-6)
    crossing = offsets[last] + fraction * (offsets[1] - offsets[0])
    return np.where(rising.any(axis=1) & (high - low > 20), crossing, np.nan)


def _gradient_centroids(profiles: NDArray[np.float32], offsets: Matrix, around: Matrix) -> Matrix:
    """Per profile, the centroid of its rising slope within 0.6 of the profile's half
    length of ``around`` (the halfway crossing).

    Where the halfway crossing of pixel-sampled light is biased by up to a tenth of a
    pixel (it depends on where the edge falls within a pixel, differently at each edge,
    which tilts the pose by degrees), the centroid of the slope is exact for a step edge
    integrated over square pixels, and for any symmetric blur of it.
    """
    slopes = np.diff(profiles, axis=1)
    centres = (offsets[:-1] + offsets[1:]) / 2
    near = np.abs(centres[None, :] - around[:, None]) <= 0.6 * offsets[-1]
    weights = np.where(near & (slopes > 0), slopes, 0.0)
    total = weights.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = (weights * centres).sum(axis=1) / total
    return np.where(np.isfinite(around) & (total > 0), centroid, np.nan)


def _fit_line(points: Matrix) -> Line:
    """Total least squares line through ``points``, refitted without those more than
    twice the median distance (and a quarter pixel) off the first fit."""
    line = _principal_line(points)
    distance = np.abs((points - line[0]) @ np.array([-line[1][1], line[1][0]]))
    keep = distance <= max(0.25, 2 * float(np.median(distance)))
    return _principal_line(points[keep]) if keep.sum() >= 2 else line


def _principal_line(points: Matrix) -> Line:
    centre = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - centre)
    return centre, axes[0]


def _intersection(first: Line, second: Line) -> Matrix:
    """Where two lines cross (NaNs for parallel lines)."""
    (p, u), (q, v) = first, second
    matrix = np.array([u, -v]).T
    if abs(np.linalg.det(matrix)) < 1e-9:
        return np.full(2, np.nan)
    t = np.linalg.solve(matrix, q - p)
    crossing: Matrix = p + t[0] * u
    return crossing


def _ippe_solutions(corners: NDArray[np.float32], size: float, matrix: Matrix) -> list[Solution]:
    """Both IPPE square poses ``(rotation, translation, reprojection error)``, best first;
    empty when solvePnP fails or places the marker behind the camera."""
    try:
        count, rvecs, tvecs, errors = cv2.solvePnPGeneric(
            marker_object_points(size), corners, matrix, None, flags=cv2.SOLVEPNP_IPPE_SQUARE
        )
    except cv2.error:  # degenerate corners (a sliver of a marker at the image edge)
        return []
    solutions = []
    for index in range(count):
        rotation = np.asarray(cv2.Rodrigues(rvecs[index])[0], np.float64)
        translation = tvecs[index].reshape(3).astype(np.float64)
        if _faces_camera((rotation, translation, 0.0)):
            solutions.append((rotation, translation, float(np.ravel(errors)[index])))
    return sorted(solutions, key=lambda s: s[2])


_FACING = np.diag([1.0, -1.0, -1.0])
"""Marker rotation facing the camera head-on: marker x right, y up, z toward the camera."""


def _ambiguous(solutions: Sequence[Solution]) -> Solution | None:
    """The runner-up of ``solutions`` (sorted by error) if it is nearly as good as the
    best, within ``AMBIGUITY_RATIO``; None if the best stands alone."""
    if len(solutions) < 2 or solutions[1][2] > AMBIGUITY_RATIO * max(solutions[0][2], 1e-3):
        return None
    return solutions[1]


def _upright_solutions(
    solutions: Sequence[Solution], corners: NDArray[np.float32], size: float, matrix: Matrix
) -> list[Solution]:
    """Poses refitted with the marker upright in a level camera's frame, starting from
    each of ``solutions`` and from their mean; distinct results, best first."""
    starts = [_upright_parameters(rotation, translation) for rotation, translation, _ in solutions]
    starts.append(np.mean(starts, axis=0))
    objects = marker_object_points(size).astype(np.float64)
    fits = [_fit_upright(start, objects, corners.astype(np.float64), matrix) for start in starts]
    distinct: list[Solution] = []
    for fit in sorted(filter(_faces_camera, fits), key=lambda s: s[2]):
        if all(float(fit[0][:, 2] @ kept[0][:, 2]) < math.cos(0.01) for kept in distinct):
            distinct.append(fit)
    return distinct


def _faces_camera(solution: Solution) -> bool:
    """Whether the marker is in front of the camera with its printed face toward it (a
    fit that turns it away has met a false minimum)."""
    rotation, translation, _ = solution
    return bool(translation[2] > 0 and rotation[:, 2] @ translation < 0)


def _upright_parameters(rotation: Matrix, translation: Matrix) -> Matrix:
    """``(yaw about the camera's y axis, tx, ty, tz)`` nearest a free pose."""
    normal = rotation[:, 2]
    return np.array([math.atan2(-normal[0], -normal[2]), *translation])


def _upright_rotation(yaw: float) -> Matrix:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ _FACING


def _reprojection(parameters: Matrix, objects: Matrix, corners: Matrix, matrix: Matrix) -> Matrix:
    """Residuals (8,) of the corners projected with upright ``parameters``."""
    points = objects @ _upright_rotation(parameters[0]).T + parameters[1:]
    depth = np.maximum(points[:, 2:3], 1e-6)
    projected = points[:, :2] / depth * (matrix[0, 0], matrix[1, 1]) + (matrix[0, 2], matrix[1, 2])
    residuals: Matrix = (projected - corners).ravel()
    return residuals


def _fit_upright(start: Matrix, objects: Matrix, corners: Matrix, matrix: Matrix) -> Solution:
    """Gauss-Newton on the four upright parameters (a few iterations converge)."""
    parameters = start.copy()
    for _ in range(10):
        residual = _reprojection(parameters, objects, corners, matrix)
        jacobian = np.empty((residual.size, 4))
        for column in range(4):
            nudged = parameters.copy()
            nudged[column] += 1e-7
            jacobian[:, column] = (
                _reprojection(nudged, objects, corners, matrix) - residual
            ) / 1e-7
        step = np.linalg.lstsq(jacobian, -residual, rcond=None)[0]
        parameters += step
        if np.abs(step).max() < 1e-9:
            break
    error = _reprojection(parameters, objects, corners, matrix)
    rms = float(np.sqrt(np.mean(error**2)))  # per coordinate, as solvePnPGeneric reports
    return _upright_rotation(parameters[0]), parameters[1:].copy(), rms


def _read_one(crop: Image | None) -> str | None:
    """The text of the one QR code in ``crop``, or None."""
    if crop is None:
        return None
    codes = zxingcpp.read_barcodes(crop, formats=_QR_FORMATS, try_rotate=False)
    return codes[0].text if codes else None


def _code_centre(code: zxingcpp.Barcode) -> NDArray[np.float64]:
    position = code.position
    corners = (position.top_left, position.top_right, position.bottom_right, position.bottom_left)
    centre: NDArray[np.float64] = np.array([[p.x, p.y] for p in corners], np.float64).mean(axis=0)
    return centre


def _with_text(detection: TagDetection, text: str | None) -> TagDetection:
    """``detection`` with its QR ``text`` and, when it parses, its payload."""
    if text is None:
        return detection
    try:
        payload: TagPayload | None = parse_payload(text)
    except TagPayloadError:
        payload = None
    return replace(detection, qr_text=text, payload=payload)
