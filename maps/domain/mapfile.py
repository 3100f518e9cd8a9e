"""ROS map_server map files: YAML metadata, images, occupancy grids, uploads and exports.

Conversion follows the rule docs/design.md states, which is Nav2's map_io on its main branch:
grey bytes, 32-bit float occupancy, thresholds compared as 32-bit floats, alpha marking
cells unknown in trinary and scale modes, raw bytes in raw mode, bottom row first.
Every failure on uploaded data raises ``MapFileError`` naming the field at fault.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import numbers
import posixpath
import re
import reprlib
import unicodedata
import warnings
import zipfile
from collections.abc import Collection, Mapping
from dataclasses import asdict, dataclass, replace
from typing import Any, Literal, TypeAlias

import numpy as np
import numpy.typing as npt
import yaml
from PIL import Image

from cloudnav_core.grid import FREE_THRESH, OCCUPIED_THRESH
from cloudnav_core.messages import header, pose_2d
from maps.exceptions import MapFileError, said

MapMode = Literal["trinary", "scale", "raw"]
MAP_MODES: tuple[MapMode, ...] = ("trinary", "scale", "raw")

Grid: TypeAlias = npt.NDArray[np.int8]
Bytes: TypeAlias = npt.NDArray[np.uint8]

OCCUPIED = 100
FREE = 0
UNKNOWN = -1

# What map_saver writes for a trinary map; its PGMs use 254 free, 0 occupied, 205 unknown.
MAP_SAVER_FREE_PIXEL = 254
MAP_SAVER_OCCUPIED_PIXEL = 0
MAP_SAVER_UNKNOWN_PIXEL = 205
RAW_UNKNOWN_PIXEL = 255

DEFAULT_MAX_ARCHIVE_BYTES = 64 * 1024 * 1024
# A map YAML is a few hundred bytes; PyYAML is slow enough that a huge one is an attack.
MAX_YAML_BYTES = 1024 * 1024

# Plain raster decoders only: Pillow's EPS plugin would hand uploaded bytes to Ghostscript.
IMAGE_FORMATS = ("PPM", "PNG", "BMP", "GIF", "JPEG", "TIFF", "WEBP")
_WIDE_GREY_MODES = frozenset({"I", "I;16", "I;16B", "I;16L", "I;16N"})
_GREY_MODES = frozenset({"1", "L", "LA", "La"})
_DRIVE_LETTER = re.compile(r"^[A-Za-z]:")
# Unicode categories of control and format characters, and line and paragraph separators.
_CONTROL_CATEGORIES = frozenset({"Cc", "Cf", "Zl", "Zp"})


@dataclass(frozen=True)
class MapMetadata:
    """The keys of a map_server YAML, as validate_metadata accepts them."""

    image: str
    resolution: float
    origin: tuple[float, float, float]
    occupied_thresh: float
    free_thresh: float
    negate: bool
    mode: MapMode = "trinary"


@dataclass(frozen=True)
class LoadedMap:
    """An uploaded map, decoded and converted; ``meta.image`` equals ``image_name``."""

    meta: MapMetadata
    image_bytes: bytes
    image_name: str
    width: int
    height: int
    grid: Grid


# Metadata


def validate_metadata(fields: Mapping[str, object]) -> MapMetadata:
    """Return the metadata that a map_server YAML mapping describes.

    Unknown keys are ignored, as map_server ignores them. Raises MapFileError naming the
    key ("image", "resolution", "origin", "occupied_thresh", "free_thresh", "negate",
    "mode") that is missing or unusable.
    """
    free, occupied = _thresholds(fields)
    return MapMetadata(
        image=_image_reference(fields),
        resolution=_resolution(fields),
        origin=_origin(fields),
        occupied_thresh=occupied,
        free_thresh=free,
        negate=_negate(fields),
        mode=_mode(fields),
    )


def parse_map_yaml(text: bytes | str) -> MapMetadata:
    """Return the metadata of a map_server YAML document.

    Raises MapFileError("yaml", ...) for text over MAX_YAML_BYTES, text that does not
    parse, or a document that is not a mapping; then validate_metadata's errors.
    """
    if len(text) > MAX_YAML_BYTES:
        raise MapFileError("yaml", f"is larger than {MAX_YAML_BYTES} bytes")
    try:
        document = yaml.safe_load(text)
    except (yaml.YAMLError, RecursionError) as exc:
        raise MapFileError("yaml", f"does not parse: {exc}") from exc
    if not isinstance(document, Mapping):
        raise MapFileError("yaml", "must be a mapping of map_server keys")
    return validate_metadata(document)


def map_yaml_text(meta: MapMetadata) -> str:
    """Return a map_server YAML document for meta, keys in map_saver's order, negate as 0/1.

    parse_map_yaml reads it back to an equal MapMetadata.
    """
    document = {
        "image": meta.image,
        "mode": meta.mode,
        "resolution": meta.resolution,
        "origin": list(meta.origin),
        "negate": int(meta.negate),
        "occupied_thresh": meta.occupied_thresh,
        "free_thresh": meta.free_thresh,
    }
    # PyYAML writes floats with repr(), which reads back bit for bit; flow style puts
    # origin on one line as map_saver does.
    return yaml.safe_dump(document, sort_keys=False, default_flow_style=None)


def content_version(image_bytes: bytes, meta: MapMetadata) -> str:
    """Return a SHA-256 hex digest that changes whenever the image or any metadata field does."""
    canonical = json.dumps(asdict(meta), sort_keys=True, separators=(",", ":"))
    # The JSON holds no raw newline, so the separator ends it unambiguously.
    digest = hashlib.sha256(canonical.encode("ascii") + b"\n")
    digest.update(image_bytes)
    return digest.hexdigest()


def _required(fields: Mapping[str, object], key: str) -> object:
    if key not in fields:
        raise MapFileError(key, "is required")
    return fields[key]


def _shown(value: object) -> str:
    return reprlib.repr(value)


def _number(key: str, value: object) -> float:
    """Return value as a finite float; raises MapFileError(key) for bools, text and inf/nan."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise MapFileError(key, f"must be a number, not {_shown(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise MapFileError(key, f"must be a finite number, not {_shown(value)}")
    return number


def _image_reference(fields: Mapping[str, object]) -> str:
    image = _required(fields, "image")
    if not isinstance(image, str) or not image.strip():
        raise MapFileError("image", f"must be a non-empty file name, not {_shown(image)}")
    return image


def _resolution(fields: Mapping[str, object]) -> float:
    resolution = _number("resolution", _required(fields, "resolution"))
    if resolution <= 0:
        raise MapFileError("resolution", f"must be greater than 0, not {resolution}")
    return resolution


def _origin(fields: Mapping[str, object]) -> tuple[float, float, float]:
    origin = _required(fields, "origin")
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise MapFileError("origin", f"must be three numbers [x, y, yaw], not {_shown(origin)}")
    x, y, yaw = (_number("origin", value) for value in origin)
    return (x, y, yaw)


def _threshold(fields: Mapping[str, object], key: str) -> float:
    value = _number(key, _required(fields, key))
    if not 0.0 <= value <= 1.0:
        raise MapFileError(key, f"must be between 0 and 1, not {value}")
    return value


def _thresholds(fields: Mapping[str, object]) -> tuple[float, float]:
    """Return (free, occupied); free must be below occupied as the conversion sees them."""
    free = _threshold(fields, "free_thresh")
    occupied = _threshold(fields, "occupied_thresh")
    # Cells are compared in 32-bit floats, where two close doubles can become equal.
    if np.float32(free) >= np.float32(occupied):
        raise MapFileError("free_thresh", f"must be less than occupied_thresh ({occupied})")
    return free, occupied


def _negate(fields: Mapping[str, object]) -> bool:
    value = _required(fields, "negate")
    # map_server reads an int, else a bool; any int but 0 or 1 here is surely a typo.
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    raise MapFileError("negate", f"must be 0, 1, true or false, not {_shown(value)}")


def _mode(fields: Mapping[str, object]) -> MapMode:
    value = fields.get("mode", "trinary")
    # map_server lower-cases the mode before matching it.
    wanted = value.lower() if isinstance(value, str) else value
    for mode in MAP_MODES:
        if wanted == mode:
            return mode
    raise MapFileError("mode", f"must be one of {', '.join(MAP_MODES)}, not {_shown(value)}")


# Images


def open_map_image(data: bytes, max_pixels: int) -> Image.Image:
    """Return the image in ``data`` (its first frame), with every pixel decoded.

    The pixel count is read from the header and checked before anything is decoded, so
    a file claiming a huge size costs nothing. Raises MapFileError("image", ...) for
    empty, unreadable, truncated or corrupt data, a zero size, or more than max_pixels
    pixels (Pillow's own decompression bomb limit also applies).
    """
    if not data:
        raise MapFileError("image", "is empty")
    with warnings.catch_warnings():
        # Pillow only warns between its bomb limit and twice it; refuse there too.
        warnings.simplefilter("error", Image.DecompressionBombWarning)
        image = _open_header(data)
        _check_pixel_count(image.size, max_pixels)
        _decode(image)
    return image


def _open_header(data: bytes) -> Image.Image:
    try:
        return Image.open(io.BytesIO(data), formats=IMAGE_FORMATS)
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        raise MapFileError("image", f"has too many pixels: {said(exc)}") from exc
    except Exception as exc:  # Pillow's plugins raise many types on hostile headers.
        raise MapFileError("image", f"is not a readable image: {said(exc)}") from exc


def _check_pixel_count(size: tuple[int, int], max_pixels: int) -> None:
    width, height = size
    if width <= 0 or height <= 0:
        raise MapFileError("image", f"has no pixels ({width}x{height})")
    if width * height > max_pixels:
        raise MapFileError(
            "image", f"has {width}x{height} pixels, more than the limit of {max_pixels}"
        )


def _decode(image: Image.Image) -> None:
    try:
        image.load()
    except Exception as exc:  # Decoders report truncation and corruption in many types.
        raise MapFileError("image", f"cannot be decoded: {said(exc)}") from exc


# Conversion


def occupancy_from_image(image: Image.Image, meta: MapMetadata) -> Grid:
    """Return the occupancy grid of a loaded image under meta's mode, thresholds and negate.

    The result is int8 of shape (height, width) whose row 0 is the image's bottom row, as
    in nav_msgs/OccupancyGrid: 100 occupied, 0 free, -1 unknown, and 1..99 in scale and
    raw modes. Raises MapFileError("image", ...) for a pixel mode Pillow cannot convert.
    """
    grey, alpha = _grey_and_alpha(image)
    cells = _cell_table(meta)[grey]
    if alpha is not None and meta.mode != "raw":
        # Nav2 marks see-through pixels unknown in trinary and scale modes, not raw.
        cells[alpha < 255] = UNKNOWN
    return np.ascontiguousarray(cells[::-1])


def _grey_and_alpha(image: Image.Image) -> tuple[Bytes, Bytes | None]:
    """Return each pixel's grey byte, and its alpha when the image has transparency."""
    if image.mode in _WIDE_GREY_MODES:
        return _byte_from_wide(np.asarray(image)), None
    normal = _normalised(image)
    pixels = np.asarray(normal)
    if normal.mode == "L":
        return pixels, None
    if normal.mode == "LA":
        return pixels[..., 0], pixels[..., 1]
    if normal.mode == "RGB":
        return _luminance(pixels), None
    return _luminance(pixels[..., :3]), pixels[..., 3]


def _normalised(image: Image.Image) -> Image.Image:
    """Return image as L, LA, RGB or RGBA, with alpha exactly when it has transparency.

    Palette and tRNS transparency become alpha, 1-bit becomes 0/255 grey.
    """
    base = "L" if image.mode in _GREY_MODES else "RGB"
    target = base + "A" if image.has_transparency_data else base
    if image.mode == target:
        return image
    try:
        return image.convert(target)
    except (ValueError, OSError) as exc:
        raise MapFileError("image", f"has an unsupported pixel mode {image.mode}") from exc


def _byte_from_wide(values: npt.NDArray[Any]) -> Bytes:
    """Return 16-bit grey as bytes, round(v / 257), as image libraries scale it."""
    wide = np.clip(values, 0, 65535).astype(np.uint32)
    grey: Bytes = ((wide + 128) // 257).astype(np.uint8)
    return grey


def _luminance(rgb: Bytes) -> Bytes:
    """Return round(0.299 R + 0.587 G + 0.114 B), halves up, per pixel.

    Integer arithmetic keeps the .5 cases exact; floats would put some on either side.
    """
    weighted = rgb[..., 0].astype(np.uint32) * 299
    weighted += rgb[..., 1].astype(np.uint32) * 587
    weighted += rgb[..., 2].astype(np.uint32) * 114
    return ((weighted + 500) // 1000).astype(np.uint8)


def _cell_table(meta: MapMetadata) -> Grid:
    """Return the cell value of each grey byte 0..255 under meta.

    A lookup table: the rule runs on 256 values, then one gather converts every pixel.
    """
    grey = np.arange(256, dtype=np.uint8)
    if meta.mode == "raw":
        return np.where(grey <= OCCUPIED, grey, UNKNOWN).astype(np.int8)
    return _thresholded(_occupancy(grey, meta.negate), meta)


def _occupancy(grey: Bytes, negate: bool) -> npt.NDArray[np.float32]:
    # 32-bit floats as Nav2 uses them: the threshold boundary cases depend on it.
    shade = grey.astype(np.float32) / np.float32(255)
    return shade if negate else np.float32(1) - shade


def _thresholded(p: npt.NDArray[np.float32], meta: MapMetadata) -> Grid:
    free = np.float32(meta.free_thresh)
    occupied = np.float32(meta.occupied_thresh)
    cells = np.full(p.shape, UNKNOWN, dtype=np.int8)
    if meta.mode == "scale":
        between = (p > free) & (p < occupied)
        cells[between] = _scaled(p[between], meta)
    cells[p <= free] = FREE
    cells[p >= occupied] = OCCUPIED
    return cells


def _scaled(p: npt.NDArray[np.float32], meta: MapMetadata) -> Grid:
    """Return 100 (p - free) / (occupied - free) rounded half away from zero.

    Computed in 32-bit floats in Nav2's order, ((p - free) / span) * 100, so results agree
    with it where they land on .5.
    """
    span = np.float32(meta.occupied_thresh - meta.free_thresh)
    value = (p - np.float32(meta.free_thresh)) / span * np.float32(100)
    whole = np.floor(value)
    # Not np.round (halves to even), nor floor(value + 0.5), which rounds 0.49999997 up.
    rounded: Grid = (whole + (value - whole >= 0.5)).astype(np.int8)
    return rounded


# Export and messages


def export_map(
    grid: npt.NDArray[Any], meta: MapMetadata, image_name: str
) -> tuple[bytes, MapMetadata]:
    """Return a binary PGM of grid and the metadata under which it loads back to grid.

    A grid of only -1, 0 and 100 is written as map_saver writes it (trinary; 254 free,
    0 occupied, 205 unknown; thresholds 0.65 and 0.196); any other as raw mode, each
    cell its own grey byte and 255 for unknown. Cells outside 0..100 count as unknown,
    as map_saver treats them. Resolution and origin are kept, negate is off, and image
    is image_name. Raises MapFileError("grid", ...) unless grid is a non-empty 2-D
    integer array.
    """
    cells = _checked_grid(grid)
    trinary = bool(np.isin(cells, (UNKNOWN, FREE, OCCUPIED)).all())
    pixels = _trinary_pixels(cells) if trinary else _raw_pixels(cells)
    exported = replace(
        meta,
        image=image_name,
        mode="trinary" if trinary else "raw",
        negate=False,
        occupied_thresh=OCCUPIED_THRESH,
        free_thresh=FREE_THRESH,
    )
    return _pgm_bytes(pixels[::-1]), exported


def occupancy_grid_message(
    grid: npt.NDArray[Any], meta: MapMetadata, frame_id: str, stamp: tuple[int, int] = (0, 0)
) -> dict[str, Any]:
    """Return grid as a nav_msgs/OccupancyGrid in rosbridge JSON.

    ``data`` lists the cells row by row from grid's row 0 (the map's bottom row); the
    origin is a geometry_msgs/Pose with the yaw as a quaternion; ``stamp`` (sec, nanosec)
    is both the header stamp and the map load time.
    """
    return {**_grid_fields(grid.shape, meta, frame_id, stamp), "data": grid.reshape(-1).tolist()}


def _grid_fields(
    shape: tuple[int, ...], meta: MapMetadata, frame_id: str, stamp: tuple[int, int]
) -> dict[str, Any]:
    height, width = shape
    sec, nanosec = stamp
    return {
        "header": header(frame_id, {"sec": sec, "nanosec": nanosec}),
        "info": {
            "map_load_time": {"sec": sec, "nanosec": nanosec},
            "resolution": meta.resolution,
            "width": width,
            "height": height,
            "origin": pose_2d(*meta.origin),
        },
    }


def occupancy_grid_json(
    grid: npt.NDArray[Any], meta: MapMetadata, frame_id: str, stamp: tuple[int, int] = (0, 0)
) -> bytes:
    """Return ``occupancy_grid_message`` as compact JSON, ``data`` written by numpy.

    The same text ``json.dumps`` gives with compact separators, several times faster on a
    large map (4096 x 4096: 2.2 s against 15 s, on a loaded machine) and with no more
    memory: every cell of ``data`` is looked up in a table of its text, and the padding
    of the table is dropped.
    """
    fields = json.dumps(_grid_fields(grid.shape, meta, frame_id, stamp), separators=(",", ":"))
    return fields.encode()[:-1] + b',"data":[' + _cells_json(grid) + b"]}"


# "<value>," for every int8, NUL-padded to five bytes; the NULs are dropped after lookup.
_CELL_TEXT = np.array([f"{v},".encode() for v in range(-128, 128)], dtype="S5")


def _cells_json(grid: npt.NDArray[Any]) -> bytes:
    cells = np.asarray(grid, dtype=np.int8).reshape(-1)
    text = _CELL_TEXT[cells.astype(np.int16) + 128].view(np.uint8)
    written: bytes = text[text != 0].tobytes()[:-1]
    return written


def _checked_grid(grid: npt.NDArray[Any]) -> Grid:
    array = np.asarray(grid)
    if array.ndim != 2 or array.size == 0 or not np.issubdtype(array.dtype, np.integer):
        raise MapFileError("grid", f"must be a non-empty 2-D integer array, not {array.dtype}")
    return np.where((array < FREE) | (array > OCCUPIED), UNKNOWN, array).astype(np.int8)


def _trinary_pixels(cells: Grid) -> Bytes:
    pixels = np.full(cells.shape, MAP_SAVER_UNKNOWN_PIXEL, dtype=np.uint8)
    pixels[cells == FREE] = MAP_SAVER_FREE_PIXEL
    pixels[cells == OCCUPIED] = MAP_SAVER_OCCUPIED_PIXEL
    return pixels


def _raw_pixels(cells: Grid) -> Bytes:
    return np.where(cells == UNKNOWN, RAW_UNKNOWN_PIXEL, cells).astype(np.uint8)


def _pgm_bytes(pixels: Bytes) -> bytes:
    height, width = pixels.shape
    return f"P5\n{width} {height}\n255\n".encode("ascii") + pixels.tobytes()


# Uploads


def load_map_upload(yaml_bytes: bytes, images: Mapping[str, bytes], max_pixels: int) -> LoadedMap:
    """Return the map that a map_server YAML and its uploaded image describe.

    ``images`` maps upload names to file contents. The YAML's image must name one of
    them by its path relative to the YAML (normalised, so ``./x.pgm`` is ``x.pgm``), or
    by base name when the upload names a file without folders. Every error surfaces
    here as MapFileError: "yaml" and the metadata keys as parse_map_yaml raises them;
    "image" for an image not in the upload, unreadable, over max_pixels, or whose name
    holds a control character.
    """
    meta = parse_map_yaml(yaml_bytes)
    name = _uploaded_image_name(meta.image, images)
    return _loaded(meta, name, images[name], max_pixels)


def load_map_archive(
    zip_bytes: bytes, max_pixels: int, max_total_bytes: int = DEFAULT_MAX_ARCHIVE_BYTES
) -> LoadedMap:
    """Return the map in a zip holding one .yaml/.yml and its image, in any folder.

    The YAML's image path resolves against the YAML's folder and must stay inside the
    archive. Raises MapFileError("archive", ...) for data that is not a zip, a member
    name that could escape a folder (absolute, ``..``, backslash, drive letter) or holds
    a control character (CR, LF, NUL, ...), members
    declaring or inflating to more than max_total_bytes, an unreadable member, or not
    exactly one YAML; "image" for an image path outside the archive or not in it; and
    load_map_upload's errors otherwise.
    """
    with _open_zip(zip_bytes) as archive:
        members = _checked_members(archive, max_total_bytes)
        yaml_name = _only_yaml(members)
        meta = parse_map_yaml(_read_member(archive, members[yaml_name], max_total_bytes))
        image_name = _archived_image_name(members, yaml_name, meta.image)
        image_bytes = _read_member(archive, members[image_name], max_total_bytes)
    return _loaded(meta, image_name, image_bytes, max_pixels)


def _loaded(meta: MapMetadata, path: str, image_bytes: bytes, max_pixels: int) -> LoadedMap:
    """Decode and convert now, so that every error surfaces at upload time."""
    # The map is stored with its YAML beside the image, so the reference is the base name.
    name = posixpath.basename(path)
    if _has_control_character(name):
        raise MapFileError("image", f"{name!r} has a control character in its name")
    image = open_map_image(image_bytes, max_pixels)
    grid = occupancy_from_image(image, meta)
    return LoadedMap(
        meta=replace(meta, image=name),
        image_bytes=image_bytes,
        image_name=name,
        width=image.width,
        height=image.height,
        grid=grid,
    )


def _uploaded_image_name(reference: str, names: Collection[str]) -> str:
    wanted = posixpath.normpath(reference)
    for name in names:
        if posixpath.normpath(name) == wanted:
            return name
    # Browsers send bare file names, so "maps/x.pgm" arrives as "x.pgm".
    base = posixpath.basename(wanted)
    if base in names:
        return base
    raise MapFileError("image", f"{reference!r} is not in the upload")


def _open_zip(data: bytes) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(io.BytesIO(data))
    except Exception as exc:  # zipfile reports damaged directories in several types.
        raise MapFileError("archive", f"is not a zip file: {said(exc)}") from exc


def _checked_members(archive: zipfile.ZipFile, max_total_bytes: int) -> dict[str, zipfile.ZipInfo]:
    """Return the archive's files by normalised name, leaving out folders and macOS extras.

    Raises MapFileError("archive", ...) for an unsafe member name, or declared sizes
    adding up to more than max_total_bytes.
    """
    infos = archive.infolist()
    for info in infos:
        _check_member_name(info.filename)
    if sum(info.file_size for info in infos) > max_total_bytes:
        raise MapFileError("archive", f"unpacks to more than {max_total_bytes} bytes")
    # Finder adds __MACOSX/ resource forks, "._map.yaml" among them, to the zips it makes.
    return {
        posixpath.normpath(info.filename): info
        for info in infos
        if not info.is_dir() and not info.filename.startswith("__MACOSX/")
    }


def _check_member_name(name: str) -> None:
    # We never extract, but an unsafe name betrays a hostile archive: refuse it whole.
    if name.startswith("/") or "\\" in name or _DRIVE_LETTER.match(name) or ".." in name.split("/"):
        raise MapFileError("archive", f"member {name!r} escapes the archive")
    if _has_control_character(name):
        raise MapFileError("archive", f"member {name!r} has a control character in its name")


def _has_control_character(name: str) -> bool:
    """Whether name holds a control, format or line-breaking character (CR, LF, NUL, ...),
    which would break the headers and files the name is later written into."""
    return any(unicodedata.category(char) in _CONTROL_CATEGORIES for char in name)


def _only_yaml(members: Mapping[str, zipfile.ZipInfo]) -> str:
    found = sorted(name for name in members if name.lower().endswith((".yaml", ".yml")))
    if not found:
        raise MapFileError("archive", "holds no .yaml file")
    if len(found) > 1:
        raise MapFileError("archive", f"holds several YAML files ({', '.join(found)})")
    return found[0]


def _archived_image_name(members: Collection[str], yaml_name: str, reference: str) -> str:
    path = posixpath.normpath(posixpath.join(posixpath.dirname(yaml_name), reference))
    if posixpath.isabs(path) or path == ".." or path.startswith("../"):
        raise MapFileError("image", f"{reference!r} points outside the archive")
    if path not in members:
        raise MapFileError("image", f"{reference!r} is not in the upload")
    return path


def _read_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, limit: int) -> bytes:
    """Return a member's bytes, reading no more than limit + 1 whatever its header claims."""
    try:
        with archive.open(info) as member:
            data = member.read(limit + 1)
    except Exception as exc:  # Encryption, bad CRCs and codecs each raise their own type.
        raise MapFileError(
            "archive", f"member {info.filename!r} cannot be read: {said(exc)}"
        ) from exc
    if len(data) > limit:
        raise MapFileError("archive", f"member {info.filename!r} inflates past {limit} bytes")
    return data
