"""A simulated pinhole camera that renders walls, floor and the tags in view.

Rendering is a column raycaster, exact for this world because every solid is a vertical
prism: one ray per image column gives the distance to the first wall or obstacle, and
the wall fills that column between the rows of the floor and of ``wall_height``. Each
tag facing the camera is drawn by perspective projection of the same artwork the server
prints (``tagart.tag_face``): warped at 4x the image resolution and reduced with
``INTER_AREA``, so small codes keep their edges the way a real sensor integrates light.
A tag column is drawn only where the tag is not farther than that column's wall (to a
few centimetres: tags are flush with their wall), so anything standing between the
camera and a tag hides it. A tag any of whose corners is behind the camera is not drawn.
People and other robots (``movers``) are drawn after the static world as flat-shaded
cylinders (one ray per column against their discs), in front of the walls they hide,
and they hide tags too. Last, a mild Gaussian blur and sensor noise.

The image is grey (``mono8``), ``model.height`` x ``model.width``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.se2 import Pose, ahead
from maps.domain.tagart import TagFace, face_size, plate_right_axis, tag_face
from robots.agent.sim.crowd import Discs, Movers, cast_discs
from robots.agent.sim.wallpaper import EAST, FAR_LEVELS, NORTH, PANEL_WIDTH, SOUTH, TEXEL, WEST
from robots.agent.sim.world import OBSTACLE, RayHits, SimTag, World

Image = NDArray[np.uint8]
Floats = NDArray[np.float64]
Depth = NDArray[np.float32]

SUPERSAMPLING = 4
NEAR = 0.05
"""Metres: a tag with a corner nearer than this to the image plane is not drawn."""
TAG_DEPTH_TOLERANCE = 0.03
"""Metres a tag may lie behind its column's wall and still show (it is on that wall)."""
SKIRTING = 0.1
"""Metres: height of the darker band at the foot of each wall."""
PAPER = (30.0, 225.0)
"""Grey levels of printed black and white under the simulated light."""
_MAX_MODULE_PIXELS = 32


class Camera:
    """Renders ``world`` as seen by a camera of ``model`` on a robot at a given pose."""

    def __init__(
        self,
        world: World,
        model: CameraModel | None = None,
        *,
        blur_sigma: float = 0.6,
        noise_sigma: float = 2.0,
        max_depth: float = 30.0,
        seed: int = 0,
        movers: Movers | None = None,
    ) -> None:
        self.world = world
        self.movers = movers
        self.model = model or CameraModel()
        self.blur_sigma = blur_sigma
        self.max_depth = max_depth
        self.rng = np.random.default_rng(seed)
        columns = np.arange(self.model.width, dtype=np.float64)
        self._column_angles = np.arctan((columns - self.model.cx) / self.model.fx)
        self._rows = np.arange(self.model.height, dtype=np.float64)[:, None]
        self._rows32 = self._rows.astype(np.float32)
        self._map_x = np.broadcast_to(
            np.arange(self.model.width, dtype=np.float32), (self.model.height, self.model.width)
        ).copy()
        self._background = np.ascontiguousarray(
            np.broadcast_to(_background(self.model), (self.model.height, self.model.width))
        )
        self._noise = _noise_banks(self.model, noise_sigma, self.rng)

    def eye(self, pose: Pose) -> Pose:
        """``(x, y, yaw)`` of the camera's optical centre on the floor plan."""
        return (*ahead(pose, self.model.mount_x), pose[2])

    def render(self, pose: Pose) -> Image:
        """The grey image seen from a robot at ``pose`` (map frame)."""
        return self.capture(pose, depth=False)[0]

    def capture(self, pose: Pose, depth: bool = True) -> tuple[Image, Depth | None]:
        """The grey image and, when ``depth``, the registered depth image (metres along
        the optical axis, float32, ``inf`` where nothing is within ``max_depth``)."""
        eye = self.eye(pose)
        # Image columns run right to left in angle: column angle is measured clockwise.
        angles = eye[2] - self._column_angles
        hits = self.world.cast(eye[0], eye[1], angles, self.max_depth)
        image = self._walls(eye, angles, hits)
        nearest = hits.distance
        if self.movers is not None:
            nearest = self._draw_movers(image, self.movers(), eye, angles, nearest)
        for tag in self.world.tags:
            self._draw_tag(image, tag, eye, nearest)
        return self._degraded(image), (self._depth(nearest) if depth else None)

    def depth_rows(self, pose: Pose, rows: NDArray[np.intp]) -> Depth:
        """Only ``rows`` of the registered depth image ``capture`` gives from ``pose``,
        without rendering the picture: what a depth-to-scan conversion reads."""
        eye = self.eye(pose)
        angles = eye[2] - self._column_angles
        nearest = self.world.cast(eye[0], eye[1], angles, self.max_depth).distance
        if self.movers is not None:
            nearest = np.minimum(nearest, cast_discs(eye[0], eye[1], angles, self.movers())[0])
        return self._depth(nearest, self._rows[rows])

    # --- walls -------------------------------------------------------------------------

    def _walls(self, eye: Pose, angles: Floats, hits: RayHits) -> Image:
        """Background with each column's wall drawn: its wallpaper for walls, a plain
        band with a skirting for obstacles, shaded by face and distance. Each column is
        its strip of texels resampled (``remap``) at the height each row sees; rows
        seeing above the wall's top or below the floor keep the background."""
        model = self.model
        depth = hits.distance * np.cos(self._column_angles)  # along the optical axis
        with np.errstate(divide="ignore"):
            scale = np.where(np.isfinite(depth), model.fy / depth, 0.0)
            per_row = np.where(scale > 0, -1.0 / (scale * TEXEL), 0.0)
        # Texel row (height above the floor) that image row r sees: at_horizon + r * per_row.
        at_horizon = np.where(scale > 0, model.mount_height / TEXEL - model.cy * per_row, -1e6)
        map_y = self._rows32 * per_row.astype(np.float32) + at_horizon.astype(np.float32)
        image = self._background.copy()
        cv2.remap(
            self._strips(eye, angles, hits), self._map_x, map_y, cv2.INTER_NEAREST,
            dst=image, borderMode=cv2.BORDER_TRANSPARENT,
        )  # fmt: skip
        return image

    def _strips(self, eye: Pose, angles: Floats, hits: RayHits) -> Image:
        """Texels seen by each column (shape: texel rows from the floor x columns), shaded."""
        shade = _wall_shade(hits.distance, hits.material, hits.x_face)
        strips = self._wallpaper_columns(eye, angles, hits)
        obstacle = hits.material == OBSTACLE
        strips[:, obstacle] = shade[obstacle]
        strips[: round(SKIRTING / TEXEL), obstacle] = (shade[obstacle] * 0.55).astype(np.uint8)
        factor = np.where(obstacle, 1.0, shade / 150.0).astype(np.float32)
        return np.asarray(np.clip(strips * factor[None, :], 0, 255), np.uint8)

    def _wallpaper_columns(self, eye: Pose, angles: Floats, hits: RayHits) -> Image:
        """Per image column, the texel column of wallpaper its ray meets (row i: i texels
        above the floor); zeros where no wall is hit."""
        world, wallpaper = self.world, self.world.wallpaper
        strips = np.zeros((wallpaper.rows, angles.size), np.uint8)
        finite = np.isfinite(hits.distance)
        hit_x = eye[0] + np.where(finite, hits.distance, 0.0) * np.cos(angles)
        hit_y = eye[1] + np.where(finite, hits.distance, 0.0) * np.sin(angles)
        facing = np.where(
            hits.x_face,
            np.where(np.cos(angles) > 0, WEST, EAST),
            np.where(np.sin(angles) > 0, SOUTH, NORTH),
        )
        across = np.where(hits.x_face, hit_x - world.origin[0], hit_y - world.origin[1])
        line = np.rint(across / world.resolution).astype(np.int64)
        along = np.where(hits.x_face, hit_y, hit_x)
        index = np.floor(along / PANEL_WIDTH).astype(np.int64)
        column = np.clip(
            ((along - index * PANEL_WIDTH) / TEXEL).astype(np.intp), 0, wallpaper.columns - 1
        )
        level = np.searchsorted(FAR_LEVELS, hits.distance)
        wanted = finite & (hits.material != OBSTACLE)
        keys = np.stack([facing, line, index, level], axis=1)[wanted]
        if keys.shape[0] == 0:
            return strips
        unique, which = np.unique(keys, axis=0, return_inverse=True)
        panels = np.stack([wallpaper.panel(*(int(k) for k in key)) for key in unique])
        strips[:, wanted] = panels[which.ravel(), :, column[wanted]].T
        return strips

    def _depth(self, distance: Floats, rows: Floats | None = None) -> Depth:
        """Registered depth: the nearer of each column's wall and the floor or ceiling
        plane each row sees (of ``rows``, shape (n, 1); all by default), along the
        optical axis."""
        model = self.model
        walls = distance * np.cos(self._column_angles)
        below = (self._rows if rows is None else rows) - model.cy
        with np.errstate(divide="ignore"):
            planes = np.where(
                below > 0,
                model.fy * model.mount_height / below,
                model.fy * (self.world.wall_height - model.mount_height) / -below,
            )
        depth = np.minimum(planes, walls[None, :])
        return np.where(depth <= self.max_depth, depth, np.inf).astype(np.float32)

    # --- people and robots ------------------------------------------------------------

    def _draw_movers(
        self, image: Image, discs: Discs, eye: Pose, angles: Floats, walls: Floats
    ) -> Floats:
        """Draw each column's nearest disc standing in front of its wall, from the floor
        to the disc's height; return each column's distance to what it shows."""
        distance, index = cast_discs(eye[0], eye[1], angles, discs)
        front = distance < walls
        if not front.any():
            return walls
        model, which = self.model, index[front].astype(np.intp)
        depth = distance[front] * np.cos(self._column_angles[front])
        scale = model.fy / np.maximum(depth, 1e-3)
        top = model.cy - scale * (discs.height[which] - model.mount_height)
        bottom = model.cy + scale * model.mount_height
        # People mid-grey, robots dark; each a little different, dimmed by distance.
        base = np.where(discs.person[which], 105.0 + 12.0 * (which % 4), 60.0)
        shade = (base * (0.6 + 0.4 * np.exp(-distance[front] / 8.0))).astype(np.uint8)
        band = (self._rows >= top) & (self._rows <= bottom)
        columns = image[:, front]
        image[:, front] = np.where(band, shade[None, :], columns)
        return np.where(front, distance, walls)

    # --- tags --------------------------------------------------------------------------

    def _draw_tag(self, image: Image, tag: SimTag, eye: Pose, walls: Floats) -> None:
        """Composite ``tag`` into ``image`` where it is in front of the camera and visible."""
        nominal = self._project(tag, _nominal_corners(tag), eye)
        if nominal is None:
            return
        face = _tag_face(tag, _module_pixels(tag, nominal[1], self.model.fx))
        projected = self._project(tag, face.corners_m(), eye)
        if projected is None:
            return
        box = _pixel_box(projected[0], self.model)
        if box is None:
            return
        alpha, grey = _warped(face, projected[0], box)
        alpha *= self._unoccluded(tag, eye, walls, box)[None, :]
        x0, y0, x1, y1 = box
        roi = image[y0:y1, x0:x1].astype(np.float32)
        image[y0:y1, x0:x1] = (roi + alpha * (grey - roi) + 0.5).astype(np.uint8)

    def _project(
        self, tag: SimTag, corners_m: NDArray[np.float32], eye: Pose
    ) -> tuple[NDArray[np.float64], float] | None:
        """Image points of face corners (metres rightward, upward from the marker centre)
        and the nearest corner's depth; None when the face is behind the camera, turned
        away from it, or too small to see."""
        ex, ey, yaw = eye
        if (ex - tag.x) * math.cos(tag.yaw) + (ey - tag.y) * math.sin(tag.yaw) <= 0:
            return None  # the camera is behind the wall the tag hangs on
        right_x, right_y = plate_right_axis(tag.yaw)
        across, up = corners_m[:, 0].astype(np.float64), corners_m[:, 1].astype(np.float64)
        dx, dy = tag.x + across * right_x - ex, tag.y + across * right_y - ey
        depth = dx * math.cos(yaw) + dy * math.sin(yaw)
        if depth.min() < NEAR:
            return None
        side = dx * math.sin(yaw) - dy * math.cos(yaw)  # rightward of the optical axis
        height = tag.height + up - self.model.mount_height
        model = self.model
        points = np.stack(
            [model.cx + model.fx * side / depth, model.cy - model.fy * height / depth], 1
        )
        return points, float(depth.min())

    def _unoccluded(
        self, tag: SimTag, eye: Pose, walls: Floats, box: tuple[int, int, int, int]
    ) -> NDArray[np.float32]:
        """Per column of ``box``, 1.0 where the tag's plane is not behind the column's wall."""
        ex, ey, yaw = eye
        angles = yaw - self._column_angles[box[0] : box[2]]
        normal = np.array([math.cos(tag.yaw), math.sin(tag.yaw)])
        facing = np.cos(angles) * normal[0] + np.sin(angles) * normal[1]
        to_plane = (tag.x - ex) * normal[0] + (tag.y - ey) * normal[1]
        with np.errstate(divide="ignore"):
            along = to_plane / facing
        visible = (along > 0) & (along <= walls[box[0] : box[2]] + TAG_DEPTH_TOLERANCE)
        unoccluded: NDArray[np.float32] = visible.astype(np.float32)
        return unoccluded

    # --- sensor ------------------------------------------------------------------------

    def _degraded(self, image: Image) -> Image:
        """Optics blur, then zero-mean sensor noise from the precomputed banks."""
        blurred = cv2.GaussianBlur(image, (0, 0), self.blur_sigma) if self.blur_sigma else image
        plus, minus = self._noise
        height, width = image.shape
        dy = int(self.rng.integers(plus.shape[0] - height + 1))
        dx = int(self.rng.integers(plus.shape[1] - width + 1))
        brighter = cv2.add(blurred, plus[dy : dy + height, dx : dx + width])
        return np.asarray(
            cv2.subtract(brighter, minus[dy : dy + height, dx : dx + width]), dtype=np.uint8
        )


# --- helpers ---------------------------------------------------------------------------


def _background(model: CameraModel) -> Image:
    """Ceiling above the horizon, floor below, each a gentle gradient (one column)."""
    rows = np.arange(model.height, dtype=np.float64)
    above = np.clip((model.cy - rows) / model.cy, 0, 1)
    below = np.clip((rows - model.cy) / (model.height - model.cy), 0, 1)
    levels = np.where(rows < model.cy, 170 + 40 * above, 95 + 35 * below)
    return levels.astype(np.uint8)[:, None]


def _wall_shade(
    distance: Floats, material: NDArray[np.uint8], x_face: NDArray[np.bool_]
) -> NDArray[np.uint8]:
    """Grey level per column: faces of the two orientations differ (light from one side),
    obstacles are darker than walls, and distance dims everything a little."""
    base = np.where(x_face, 165.0, 135.0)
    base = np.where(material == OBSTACLE, base * 0.55, base)
    dimming = 0.6 + 0.4 * np.exp(-np.nan_to_num(distance, posinf=1e3) / 8.0)
    return (base * dimming).astype(np.uint8)


def _noise_banks(model: CameraModel, sigma: float, rng: np.random.Generator) -> tuple[Image, Image]:
    """Positive and negative parts of a Gaussian noise field a little larger than a
    frame; each frame uses a random window, which costs two saturating adds."""
    shape = (model.height + 64, model.width + 64)
    noise = np.rint(rng.normal(0.0, sigma, shape)) if sigma > 0 else np.zeros(shape)
    return np.clip(noise, 0, 255).astype(np.uint8), np.clip(-noise, 0, 255).astype(np.uint8)


def _nominal_corners(tag: SimTag) -> NDArray[np.float32]:
    """Face corners from the layout alone (before choosing a drawing density)."""
    width, height = face_size(tag.size)
    left, top = -0.75 * tag.size, height / 2
    right, bottom = left + width, top - height
    return np.array([(left, top), (right, top), (right, bottom), (left, bottom)], np.float32)


def _module_pixels(tag: SimTag, nearest_depth: float, fx: float) -> int:
    """Face pixels per QR module: a power of two near the supersampled image's pixels per
    module at the tag's nearest corner, so the warp neither aliases nor wastes time."""
    module = tag.size / _qr_modules(tag.qr_version)
    wanted = SUPERSAMPLING * fx * module / nearest_depth
    return int(min(2 ** max(math.floor(math.log2(max(wanted, 1.0))), 0), _MAX_MODULE_PIXELS))


def _qr_modules(version: int) -> int:
    return 17 + 4 * version


@lru_cache(maxsize=128)
def _tag_face(tag: SimTag, module_pixels: int) -> TagFace:
    """The tag's face drawn with exactly ``module_pixels`` pixels per QR module."""
    pixels_per_metre = module_pixels * _qr_modules(tag.qr_version) / tag.size
    return tag_face(
        tag.marker_id, tag.payload, tag.dictionary, pixels_per_metre, tag.size, tag.qr_version
    )


def _pixel_box(points: Floats, model: CameraModel) -> tuple[int, int, int, int] | None:
    """Integer pixel box ``(x0, y0, x1, y1)`` (end exclusive) covering ``points`` inside the
    image, or None when the face misses the image or spans under two pixels."""
    x0, y0 = np.floor(points.min(axis=0)).astype(int)
    x1, y1 = np.ceil(points.max(axis=0)).astype(int) + 1
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    x0, y0 = max(int(x0), 0), max(int(y0), 0)
    x1, y1 = min(int(x1), model.width), min(int(y1), model.height)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def _warped(
    face: TagFace, points: Floats, box: tuple[int, int, int, int]
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Coverage (0..1) and grey level of the face over ``box``: warped at 4x, then each
    image pixel the mean of its 4x4 sub-pixels."""
    x0, y0, x1, y1 = box
    s = SUPERSAMPLING
    # Pixel centres sit at integers, so image pixel i spans sub-pixels s*i .. s*i + s - 1.
    target = (points - (x0, y0)) * s + (s - 1) / 2
    transform = cv2.getPerspectiveTransform(face.corners_px(), target.astype(np.float32))
    source = np.dstack([face.image, np.full_like(face.image, 255)])
    size = ((x1 - x0) * s, (y1 - y0) * s)
    sharp = cv2.warpPerspective(source, transform, size, flags=cv2.INTER_LINEAR)
    reduced = cv2.resize(sharp, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    alpha = reduced[:, :, 1].astype(np.float32) * np.float32(1 / 255)
    ink = reduced[:, :, 0].astype(np.float32) / np.maximum(reduced[:, :, 1], 1)
    return alpha, np.asarray(PAPER[0] + (PAPER[1] - PAPER[0]) * ink, dtype=np.float32)
