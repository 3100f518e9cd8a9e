"""Telemetry's stored state: what each building records and keeps."""

from __future__ import annotations

from django.core.validators import MaxValueValidator, MinValueValidator
from django.db import models

from maps.models import Building

# Each robot's topics (relative to its namespace) recorded unless a building chooses others.
DEFAULT_RECORDED = ["pose", "odom", "scan", "plan", "nav_status", "map_id", "cmd_vel"]
CAMERA_TOPIC = "camera/image/compressed"


def default_recorded() -> list[str]:
    return list(DEFAULT_RECORDED)


class RecordingSettings(models.Model):
    """What a building's robots have recorded and how long it is kept.

    ``topics`` are robot topic names relative to the robot (``pose``, ``scan``); the camera
    is recorded only when ``camera_rate`` (frames per second) is above zero. Files older
    than ``retention_days`` go, and the oldest go first once the building's robots hold
    more than ``budget_mb`` megabytes. A building without settings records the defaults.
    """

    building = models.OneToOneField(
        Building, models.CASCADE, primary_key=True, related_name="recording"
    )
    enabled = models.BooleanField(default=True)
    topics = models.JSONField(default=default_recorded)
    camera_rate = models.FloatField(
        default=0.0, validators=[MinValueValidator(0.0), MaxValueValidator(30.0)]
    )
    retention_days = models.PositiveIntegerField(
        default=14, validators=[MinValueValidator(1), MaxValueValidator(3650)]
    )
    budget_mb = models.PositiveIntegerField(default=10_240, validators=[MinValueValidator(1)])

    class Meta:
        verbose_name_plural = "recording settings"

    def __str__(self) -> str:
        return f"recording of {self.building_id}"
