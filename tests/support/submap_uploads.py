"""Sub-map uploads as the API takes them: the URL, a valid map pair, bad uploads, the post."""

from __future__ import annotations

import io
import zipfile
from typing import Any

from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile

from tests.conftest import client_for, map_pgm, map_yaml

URL = "/api/buildings/boccioni_1/maps/"


def pair(**kwargs: Any) -> dict[str, Any]:
    kwargs.setdefault("code", "CorridorA")
    kwargs.setdefault("image", SimpleUploadedFile("map.pgm", map_pgm()))
    kwargs.setdefault("yaml", SimpleUploadedFile("map.yaml", map_yaml()))
    return {k: v for k, v in kwargs.items() if v is not None}


def zipped(members: dict[str, bytes]) -> SimpleUploadedFile:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return SimpleUploadedFile("map.zip", out.getvalue())


def fresh(upload: SimpleUploadedFile) -> SimpleUploadedFile:
    """A copy of an unread upload, which is left unread."""
    data = upload.read()
    upload.seek(0)
    return SimpleUploadedFile(upload.name or "", data)


def unread(change: dict[str, Any]) -> dict[str, Any]:
    """``change`` with copies of its uploads: BAD_UPLOADS' files are shared by the tests
    of both upload endpoints, so each test sends copies and leaves them unread."""
    return {k: fresh(v) if isinstance(v, SimpleUploadedFile) else v for k, v in change.items()}


def post(user: User, data: dict[str, Any]) -> Any:
    return client_for(user).post(URL, data, format="multipart")


BAD_UPLOADS: list[tuple[str, dict[str, Any], str]] = [
    ("truncated image", {"image": SimpleUploadedFile("map.pgm", map_pgm()[:-100])}, "image"),
    ("garbage image", {"image": SimpleUploadedFile("map.pgm", b"not an image at all")}, "image"),
    ("yaml not a mapping", {"yaml": SimpleUploadedFile("m.yaml", b"- 1\n- 2\n")}, "yaml"),
    ("yaml unparsable", {"yaml": SimpleUploadedFile("m.yaml", b"a: [1, \n")}, "yaml"),
    (
        "missing resolution",
        {
            "yaml": SimpleUploadedFile(
                "m.yaml",
                map_yaml().replace(b"resolution: 0.05\n", b""),
            )
        },
        "resolution",
    ),
    (
        "resolution as text",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(resolution="fine"))},
        "resolution",
    ),
    (
        "negative resolution",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(resolution=-0.05))},
        "resolution",
    ),
    (
        "zero resolution",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(resolution=0))},
        "resolution",
    ),
    (
        "origin of two numbers",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(origin=[0, 0]))},
        "origin",
    ),
    ("origin of text", {"yaml": SimpleUploadedFile("m.yaml", map_yaml(origin="here"))}, "origin"),
    (
        "threshold above one",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(occupied_thresh=1.5))},
        "occupied_thresh",
    ),
    (
        "negative threshold",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(free_thresh=-0.1))},
        "free_thresh",
    ),
    (
        "free at occupied",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(free_thresh=0.65))},
        "free_thresh",
    ),
    ("unknown mode", {"yaml": SimpleUploadedFile("m.yaml", map_yaml(mode="fancy"))}, "mode"),
    (
        "image not in upload",
        {"yaml": SimpleUploadedFile("m.yaml", map_yaml(image="other.pgm"))},
        "image",
    ),
    ("no yaml", {"yaml": None}, "yaml"),
    ("no image", {"image": None}, "image"),
    ("bad code", {"code": "1 bad/code"}, "code"),
]
