"""Test override: the same settings, with fast password hashing and a file-based test database.

The test database is a file (not SQLite's in-memory default) so that a live daphne started
by ``tests.fixtures_live`` in a subprocess opens the very database the test writes to. Its
name carries the test run's process id, so two runs in one checkout never share it.
"""

from __future__ import annotations

import os
from pathlib import Path

from .settings import *  # noqa: F403
from .settings import ALLOWED_HOSTS, BASE_DIR, DATABASES, env_bool

SECRET_KEY = "cloudnav-tests-only-key"
# Django's test client and Channels' communicator name this host.
ALLOWED_HOSTS = [*ALLOWED_HOSTS, "testserver"]
# Sign-in rate limits apply where a test turns them on (tests/test_signin_limits.py): the
# other tests sign in many times from one address, and some check passwords without a request.
AXES_ENABLED = False
PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]

if DATABASES["default"]["ENGINE"] == "django.db.backends.sqlite3":
    (BASE_DIR / "var").mkdir(exist_ok=True)
    DATABASES["default"]["TEST"] = {"NAME": str(BASE_DIR / "var" / f"test-{os.getpid()}.sqlite3")}

# The test run itself is always embedded; live servers that ``tests.fixtures_live`` starts
# (``CLOUDNAV_LIVE_SERVER=1``) take their mode, scaled or not, from the environment given.
if not env_bool("CLOUDNAV_LIVE_SERVER", False):
    REDIS_URL = ""
    CHANNEL_LAYERS = {"default": {"BACKEND": "channels.layers.InMemoryChannelLayer"}}

# Keyframe files of test runs go apart from the demo's (a live server inherits the path,
# unless a test gives its servers a directory of their own).
# Each pytest-xdist worker has its own.
_KEYFRAMES = f"test-keyframes-{os.environ.get('PYTEST_XDIST_WORKER', 'gw0')}"
CLOUDNAV_KEYFRAME_DIR = Path(
    os.environ.get("CLOUDNAV_KEYFRAME_DIR", str(BASE_DIR / "var" / _KEYFRAMES))
)
_MAPS3D = f"test-maps3d-{os.environ.get('PYTEST_XDIST_WORKER', 'gw0')}"
CLOUDNAV_MAP3D_DIR = Path(os.environ.get("CLOUDNAV_MAP3D_DIR", str(BASE_DIR / "var" / _MAPS3D)))
# Servers under test record only when a test gives them a directory of its own.
CLOUDNAV_RECORDING = bool(os.environ.get("CLOUDNAV_RECORDING_DIR"))
