"""The rosbridge server's tunables: a Django setting if defined, else the environment, else
the default, so a deployment (or a test's live server) can set them either way.

The limits bound what one connection can make the server hold or do, and what all of
them together can; the README's configuration table lists each with its meaning.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from django.conf import settings

from telemetry.domain.decoding import FrameLimits
from telemetry.domain.events import STUCK_AFTER_S
from telemetry.domain.limits import ConnectionLimits

T = TypeVar("T")


def setting(name: str, default: T, cast: Callable[[str], T]) -> T:
    value: T | None = getattr(settings, name, None)
    if value is not None:
        return value
    raw = os.environ.get(name)
    return default if raw is None or raw == "" else cast(raw)


MIB = 2**20


def _flag(raw: str) -> bool:
    """An on/off setting from the environment: 0, false, off and no are off."""
    return raw.strip().lower() not in {"0", "false", "off", "no"}


@dataclass(frozen=True)
class RosbridgeConfig:
    max_frame_bytes: int
    frame: FrameLimits
    per_connection: ConnectionLimits
    fragments_total_bytes: int
    fragment_timeout: float
    # What all the connections of one person or robot may hold of fragmented messages, so
    # that one viewer's many sockets cannot take the whole server's budget.
    fragments_per_client_bytes: int
    max_send_bytes: int
    send_queue_frames: int
    send_queue_bytes: int
    teleop_lock_ttl: float
    teleop_silence: float
    teleop_handover: float
    fleet_flush_interval: float
    stuck_after: float
    right_of_way: bool
    stuck_give_up_after: float
    redis_url: str

    @classmethod
    def load(cls) -> RosbridgeConfig:
        max_frame_bytes = setting("CLOUDNAV_ROSBRIDGE_MAX_FRAME_BYTES", 16 * MIB, int)
        return cls(
            max_frame_bytes=max_frame_bytes,
            frame=FrameLimits(
                max_bytes=max_frame_bytes,
                max_nodes=setting("CLOUDNAV_ROSBRIDGE_MAX_FRAME_VALUES", 2**20, int),
                max_depth=setting("CLOUDNAV_ROSBRIDGE_MAX_FRAME_DEPTH", 64, int),
            ),
            per_connection=ConnectionLimits(
                subscriptions=setting("CLOUDNAV_ROSBRIDGE_MAX_SUBSCRIPTIONS", 1024, int),
                advertisements=setting("CLOUDNAV_ROSBRIDGE_MAX_ADVERTISEMENTS", 256, int),
                services=setting("CLOUDNAV_ROSBRIDGE_MAX_SERVICES", 256, int),
                pending_calls=setting("CLOUDNAV_ROSBRIDGE_MAX_PENDING_CALLS", 1024, int),
                params=setting("CLOUDNAV_ROSBRIDGE_MAX_PARAMS", 256, int),
                param_bytes=setting("CLOUDNAV_ROSBRIDGE_MAX_PARAM_BYTES", 4 * MIB, int),
                fragment_bytes=setting("CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES", 4 * MIB, int),
                min_fragment_size=setting("CLOUDNAV_ROSBRIDGE_MIN_FRAGMENT_SIZE", 1024, int),
                latched_bytes=setting("CLOUDNAV_ROSBRIDGE_MAX_LATCHED_BYTES", 16 * MIB, int),
            ),
            fragments_total_bytes=setting("CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES_TOTAL", 32 * MIB, int),
            fragment_timeout=setting("CLOUDNAV_ROSBRIDGE_FRAGMENT_TIMEOUT", 10.0, float),
            fragments_per_client_bytes=setting(
                "CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES_PER_CLIENT", 8 * MIB, int
            ),
            max_send_bytes=setting("CLOUDNAV_ROSBRIDGE_MAX_SEND_BYTES", 2 * max_frame_bytes, int),
            send_queue_frames=setting("CLOUDNAV_ROSBRIDGE_SEND_QUEUE_FRAMES", 256, int),
            send_queue_bytes=setting("CLOUDNAV_ROSBRIDGE_SEND_QUEUE_BYTES", 8 * MIB, int),
            teleop_lock_ttl=setting("CLOUDNAV_TELEOP_LOCK_TTL", 5.0, float),
            teleop_silence=setting("CLOUDNAV_TELEOP_SILENCE", 0.5, float),
            teleop_handover=setting("CLOUDNAV_TELEOP_HANDOVER", 5.0, float),
            fleet_flush_interval=setting("CLOUDNAV_FLEET_FLUSH_INTERVAL", 1.0, float),
            stuck_after=setting("CLOUDNAV_STUCK_AFTER", STUCK_AFTER_S, float),
            right_of_way=setting("CLOUDNAV_RIGHT_OF_WAY", True, _flag),
            stuck_give_up_after=setting("CLOUDNAV_STUCK_GIVE_UP_AFTER", 60.0, float),
            redis_url=getattr(settings, "REDIS_URL", "") or "",
        )
