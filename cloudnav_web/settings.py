"""CloudNav settings, read from the environment with zero-config defaults.

Embedded mode (no variables): SQLite and Channels' in-memory layer.
Scaled mode: ``DATABASE_URL=postgres://...`` and ``REDIS_URL=redis://...``.
"""

from __future__ import annotations

import json
import os
from datetime import timedelta
from pathlib import Path
from typing import Any

import dj_database_url
import django_stubs_ext

# Lets the classes django-stubs makes generic take their type at runtime too, as in
# ``admin.ModelAdmin[Building]`` (mypy runs in strict mode).
django_stubs_ext.monkeypatch()

BASE_DIR = Path(__file__).resolve().parent.parent


def env_bool(name: str, default: bool) -> bool:
    value = os.environ.get(name)
    if value is None:
        return default
    return value.strip().lower() in {"1", "true", "yes", "on"}


def env_list(name: str, default: str) -> list[str]:
    return [item.strip() for item in os.environ.get(name, default).split(",") if item.strip()]


DEBUG = env_bool("DEBUG", False)
# The demo (``make demo``, the benchmarks' servers) says so; outside it the server refuses
# to start with the public default key (``cloudnav_web.deployment``).
CLOUDNAV_DEMO = env_bool("CLOUDNAV_DEMO", False)
DEMO_SECRET_KEY = "cloudnav-embedded-demo-key-change-me-in-production"
SECRET_KEY = os.environ.get("SECRET_KEY", DEMO_SECRET_KEY)
ALLOWED_HOSTS = env_list("ALLOWED_HOSTS", "127.0.0.1,localhost,[::1]")
CSRF_TRUSTED_ORIGINS = env_list(
    "CSRF_TRUSTED_ORIGINS", "http://127.0.0.1:8000,http://localhost:8000"
)

# The address robots reach the cloud at; it is printed in every tag's QR code.
CLOUDNAV_PUBLIC_URL = os.environ.get("CLOUDNAV_PUBLIC_URL", "http://127.0.0.1:8000")
# Uploaded map images larger than this are refused before they are decoded.
# The visual map: keyframe files, the ingestion queue, and image limits (docs/design.md).
CLOUDNAV_KEYFRAME_DIR = Path(
    os.environ.get("CLOUDNAV_KEYFRAME_DIR", str(BASE_DIR / "var" / "keyframes"))
)
# The 3D maps (PLY cloud, OctoMap) published with visual sessions' sub-map versions.
CLOUDNAV_MAP3D_DIR = Path(os.environ.get("CLOUDNAV_MAP3D_DIR", str(BASE_DIR / "var" / "maps3d")))
CLOUDNAV_KEYFRAME_QUEUE = int(os.environ.get("CLOUDNAV_KEYFRAME_QUEUE", "32"))
CLOUDNAV_MAX_IMAGE_PIXELS = int(os.environ.get("CLOUDNAV_MAX_IMAGE_PIXELS", str(1280 * 960)))
CLOUDNAV_RELOCALISE_WORKERS = int(os.environ.get("CLOUDNAV_RELOCALISE_WORKERS", "2"))
# Relocalisation calls waiting for a worker, per lane (robots, people): maps/visual/lanes.py.
CLOUDNAV_RELOCALISE_QUEUE = int(os.environ.get("CLOUDNAV_RELOCALISE_QUEUE", "8"))
CLOUDNAV_MAX_MAP_PIXELS = int(os.environ.get("CLOUDNAV_MAX_MAP_PIXELS", str(4096 * 4096)))
CLOUDNAV_MAX_UPLOAD_BYTES = int(os.environ.get("CLOUDNAV_MAX_UPLOAD_BYTES", str(32 * 1024 * 1024)))
DATA_UPLOAD_MAX_MEMORY_SIZE = CLOUDNAV_MAX_UPLOAD_BYTES
FILE_UPLOAD_MAX_MEMORY_SIZE = CLOUDNAV_MAX_UPLOAD_BYTES
# Request bodies (cloudnav_web.bodies): past this size only clients with credentials that
# hold may send one, and none may pass the second limit (an upload's two files and more).
CLOUDNAV_ANONYMOUS_BODY_BYTES = int(os.environ.get("CLOUDNAV_ANONYMOUS_BODY_BYTES", "65536"))
# A request's headers must all arrive within this many seconds (cloudnav_web.headers).
CLOUDNAV_HEADER_SECONDS = float(os.environ.get("CLOUDNAV_HEADER_SECONDS", "10"))
CLOUDNAV_MAX_BODY_BYTES = int(
    os.environ.get("CLOUDNAV_MAX_BODY_BYTES", str(2 * CLOUDNAV_MAX_UPLOAD_BYTES + 2**20))
)
# Heavy answers (tag sheets and prints, map grids, video encoders) share a budget: at most
# this many at once, this much memory (estimated) among them, this many per client; beyond
# it they are answered 503 (or 429 for the client's own share) with Retry-After.
CLOUDNAV_HEAVY_SLOTS = int(os.environ.get("CLOUDNAV_HEAVY_SLOTS", "4"))
CLOUDNAV_HEAVY_MEMORY_BYTES = int(os.environ.get("CLOUDNAV_HEAVY_MEMORY_BYTES", str(2**30)))
CLOUDNAV_HEAVY_PER_CLIENT = int(os.environ.get("CLOUDNAV_HEAVY_PER_CLIENT", "2"))
# Video encoders (VP8, and MJPEG re-encoded to another size or quality) have their own
# budget, held for as long as someone watches; viewers asking the same share one encoder.
CLOUDNAV_VIDEO_ENCODER_SLOTS = int(os.environ.get("CLOUDNAV_VIDEO_ENCODER_SLOTS", "8"))
CLOUDNAV_VIDEO_ENCODER_MEMORY_BYTES = int(
    os.environ.get("CLOUDNAV_VIDEO_ENCODER_MEMORY_BYTES", str(2**30))
)
CLOUDNAV_VIDEO_ENCODER_PER_CLIENT = int(os.environ.get("CLOUDNAV_VIDEO_ENCODER_PER_CLIENT", "4"))
# Recording exports (.mcap, .bag) have theirs too, held until the file has been sent: each
# holds about CLOUDNAV_EXPORT_BYTES (a chunk being written, one being read), whatever its range.
CLOUDNAV_EXPORT_SLOTS = int(os.environ.get("CLOUDNAV_EXPORT_SLOTS", "8"))
CLOUDNAV_EXPORT_MEMORY_BYTES = int(os.environ.get("CLOUDNAV_EXPORT_MEMORY_BYTES", str(2**28)))
CLOUDNAV_EXPORT_PER_CLIENT = int(os.environ.get("CLOUDNAV_EXPORT_PER_CLIENT", "2"))
# WebRTC (/whep): ICE servers as a JSON list of {"urls": ..., "username": ..., "credential":
# ...} (STUN or TURN, for peers behind NAT; none: host candidates only, enough on a LAN),
# and how many WebRTC sessions one client (a person or a robot) may hold at a time.
CLOUDNAV_WEBRTC_ICE_SERVERS: list[dict[str, Any]] = json.loads(
    os.environ.get("CLOUDNAV_WEBRTC_ICE_SERVERS", "[]")
)
CLOUDNAV_WHEP_PER_CLIENT = int(os.environ.get("CLOUDNAV_WHEP_PER_CLIENT", "8"))
# Seconds a WebRTC session may take to connect; one that has not by then is dropped, and
# its encoder (and its share of the video budget) released.
CLOUDNAV_WHEP_CONNECT_TIMEOUT = float(os.environ.get("CLOUDNAV_WHEP_CONNECT_TIMEOUT", "15"))

INSTALLED_APPS = [
    "daphne",
    "django.contrib.admin",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "rest_framework",
    "drf_spectacular",
    "drf_spectacular_sidecar",
    "channels",
    "axes",
    "maps",
    "robots",
    "telemetry",
    "benchmarks",  # for its `bench` command only (see benchmarks/__init__.py)
]

MIDDLEWARE = [
    "django.middleware.security.SecurityMiddleware",
    # Serves static files (browser libraries from npm, the API docs' assets) under daphne.
    "whitenoise.middleware.WhiteNoiseMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
    # Answers 429 to a sign-in from a name and address that failed too often (below).
    "axes.middleware.AxesMiddleware",
    # The database out of reach: 503 with Retry-After, logged once per 10 s (outage.py).
    "cloudnav_django.outage.DatabaseOutageMiddleware",
]

# Sign-in attempts (the login page, the admin, HTTP Basic on the API) are rate-limited by
# django-axes: it counts failures where Django authenticates, so every way of signing in
# is covered, and keeps them in the database, so every server process shares the count.
# A name and address pair that failed CLOUDNAV_SIGNIN_FAILURES times is refused (429,
# even with the right password) for CLOUDNAV_SIGNIN_COOLOFF_MINUTES. The pair, not the
# address alone, so people behind one proxy do not lock each other out, nor can anyone
# lock a user out from elsewhere.
AUTHENTICATION_BACKENDS = [
    "axes.backends.AxesStandaloneBackend",
    "django.contrib.auth.backends.ModelBackend",
]
AXES_FAILURE_LIMIT = int(os.environ.get("CLOUDNAV_SIGNIN_FAILURES", "5"))
AXES_COOLOFF_TIME = timedelta(
    minutes=float(os.environ.get("CLOUDNAV_SIGNIN_COOLOFF_MINUTES", "15"))
)
AXES_LOCKOUT_PARAMETERS = [["username", "ip_address"]]
AXES_RESET_ON_SUCCESS = True
AXES_HTTP_RESPONSE_CODE = 429
# A locked-out sign-in on the login page gets a page that says so, not bare text.
AXES_LOCKOUT_TEMPLATE = "registration/locked_out.html"

ROOT_URLCONF = "cloudnav_web.urls"
ASGI_APPLICATION = "cloudnav_web.asgi.application"

TEMPLATES = [
    {
        "BACKEND": "django.template.backends.django.DjangoTemplates",
        "DIRS": [BASE_DIR / "templates"],
        "APP_DIRS": True,
        "OPTIONS": {
            "context_processors": [
                "django.template.context_processors.request",
                "django.contrib.auth.context_processors.auth",
                "django.contrib.messages.context_processors.messages",
            ],
        },
    },
]

DATABASES = {
    "default": dj_database_url.parse(
        os.environ.get("DATABASE_URL", f"sqlite:///{BASE_DIR / 'db.sqlite3'}"),
        conn_max_age=int(os.environ.get("DB_CONN_MAX_AGE", "0")),
    )
}
if DATABASES["default"]["ENGINE"] == "django.db.backends.sqlite3":
    # SQLite serves one writer at a time. A transaction takes the write lock when it begins
    # (IMMEDIATE): one that began reading and then wrote could not wait for the lock and
    # failed at once with "database is locked". Writers wait for it up to ``timeout``
    # seconds; with WAL, readers never wait for a writer, nor a writer for readers.
    DATABASES["default"].setdefault("OPTIONS", {}).update(
        timeout=20,
        transaction_mode="IMMEDIATE",
        init_command="PRAGMA journal_mode=WAL",
    )

REDIS_URL = os.environ.get("REDIS_URL", "")
if REDIS_URL:
    CHANNEL_LAYERS = {
        "default": {
            "BACKEND": "channels_redis.core.RedisChannelLayer",
            # a socket timeout longer than channels_redis' 5 s blocking pop, or a receive
            # in a lull fails with redis-py's default 5 s timeout (telemetry.rosbridge.relay)
            "CONFIG": {
                "hosts": [{"address": REDIS_URL, "socket_timeout": 15}],
                "capacity": 1000,
                "expiry": 10,
            },
        }
    }
else:
    CHANNEL_LAYERS = {"default": {"BACKEND": "channels.layers.InMemoryChannelLayer"}}

DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

AUTH_PASSWORD_VALIDATORS = [
    {"NAME": "django.contrib.auth.password_validation.UserAttributeSimilarityValidator"},
    {"NAME": "django.contrib.auth.password_validation.MinimumLengthValidator"},
]

LANGUAGE_CODE = "en-us"
TIME_ZONE = "UTC"
USE_I18N = True
USE_TZ = True

STATIC_URL = "static/"
STATICFILES_DIRS = [BASE_DIR / "static"]
# Set STATIC_ROOT to serve collected files (``manage.py collectstatic``); without it,
# WhiteNoise finds files where Django's finders do.
STATIC_ROOT = os.environ.get("STATIC_ROOT") or None
WHITENOISE_USE_FINDERS = True
WHITENOISE_AUTOREFRESH = DEBUG

LOGIN_URL = "/accounts/login/"
LOGIN_REDIRECT_URL = "/"
LOGOUT_REDIRECT_URL = "/accounts/login/"

REST_FRAMEWORK = {
    "DEFAULT_AUTHENTICATION_CLASSES": [
        "robots.authentication.RobotTokenAuthentication",
        "rest_framework.authentication.SessionAuthentication",
        "cloudnav_web.signin.RateLimitedBasicAuthentication",
    ],
    "DEFAULT_PERMISSION_CLASSES": ["rest_framework.permissions.IsAuthenticated"],
    "DEFAULT_SCHEMA_CLASS": "drf_spectacular.openapi.AutoSchema",
    "EXCEPTION_HANDLER": "cloudnav_web.errors.exception_handler",
    "UNAUTHENTICATED_USER": "django.contrib.auth.models.AnonymousUser",
}

SPECTACULAR_SETTINGS = {
    "TITLE": "CloudNav API",
    "DESCRIPTION": "Cloud maps for global navigation of robot fleets.",
    "VERSION": "1.0.0",
    "SERVE_INCLUDE_SCHEMA": False,
    "SWAGGER_UI_DIST": "SIDECAR",
    "SWAGGER_UI_FAVICON_HREF": "SIDECAR",
    "REDOC_DIST": "SIDECAR",
    "COMPONENT_SPLIT_REQUEST": True,
}

LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {"plain": {"format": "%(asctime)s %(levelname)s %(name)s: %(message)s"}},
    # Robot tokens never reach a log (cloudnav_web.redaction; daphne's access log too).
    "filters": {"redact": {"()": "cloudnav_web.redaction.RedactingFilter"}},
    "handlers": {
        "console": {"class": "logging.StreamHandler", "formatter": "plain", "filters": ["redact"]}
    },
    "root": {"handlers": ["console"], "level": os.environ.get("LOG_LEVEL", "INFO")},
    "loggers": {
        "django.request": {"level": "ERROR"},
        # daphne's access log (cloudnav_web.access_log): DEBUG adds the unchanged checks (304)
        "cloudnav_web.access": {"level": os.environ.get("CLOUDNAV_ACCESS_LOG_LEVEL") or "INFO"},
    },
}
