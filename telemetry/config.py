"""The rosbridge server's tunables: a Django setting if defined, else the environment, else
the default, so a deployment (or a test's live server) can set them either way."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from django.conf import settings

T = TypeVar("T")


def setting(name: str, default: T, cast: Callable[[str], T]) -> T:
    value = getattr(settings, name, None)
    if value is not None:
        return value
    raw = os.environ.get(name)
    return default if raw is None or raw == "" else cast(raw)


@dataclass(frozen=True)
class RosbridgeConfig:
    max_frame_bytes: int
    send_queue_frames: int
    send_queue_bytes: int
    teleop_lock_ttl: float
    teleop_silence: float
    fleet_flush_interval: float
    redis_url: str

    @classmethod
    def load(cls) -> RosbridgeConfig:
        return cls(
            max_frame_bytes=setting("CLOUDNAV_ROSBRIDGE_MAX_FRAME_BYTES", 16 * 2**20, int),
            send_queue_frames=setting("CLOUDNAV_ROSBRIDGE_SEND_QUEUE_FRAMES", 256, int),
            send_queue_bytes=setting("CLOUDNAV_ROSBRIDGE_SEND_QUEUE_BYTES", 8 * 2**20, int),
            teleop_lock_ttl=setting("CLOUDNAV_TELEOP_LOCK_TTL", 5.0, float),
            teleop_silence=setting("CLOUDNAV_TELEOP_SILENCE", 0.5, float),
            fleet_flush_interval=setting("CLOUDNAV_FLEET_FLUSH_INTERVAL", 1.0, float),
            redis_url=getattr(settings, "REDIS_URL", "") or "",
        )
