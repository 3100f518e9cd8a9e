"""Telemetry's rows: the events the server derives from the fleet (``telemetry.events``)
and what each building records and keeps (``telemetry.recording``).

The topic bus itself lives in memory and the channel layer.
"""

from __future__ import annotations

from django.conf import settings
from django.core.validators import MaxValueValidator, MinValueValidator
from django.db import models

from maps.models import Building
from robots.models import Robot
from telemetry.domain.events import Kind, Severity

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


class Event(models.Model):
    """Something that happened: when, where, to which robot, what, how bad, who caused it.

    ``actor`` is ``server``, ``robot:<name>`` or ``user:<name>``; ``data`` the values behind
    ``message``. An alert (``alert``) stays open until acknowledged or cleared
    (``cleared_at``: its condition ended, told by a later ``alert_cleared`` or other event
    naming it in ``data["cleared"]``). A recording carries
    the same fields, so events can be listed and filtered the same way there.
    """

    time = models.DateTimeField(db_index=True)
    building = models.ForeignKey(
        Building, null=True, blank=True, on_delete=models.SET_NULL, related_name="events"
    )
    robot = models.ForeignKey(
        Robot, null=True, blank=True, on_delete=models.SET_NULL, related_name="events"
    )
    kind = models.CharField(max_length=40, choices=[(k.value, k.value) for k in Kind])
    severity = models.CharField(max_length=10, choices=[(s.value, s.value) for s in Severity])
    actor = models.CharField(max_length=160, default="server")
    message = models.CharField(max_length=500)
    data = models.JSONField(default=dict, blank=True)
    alert = models.BooleanField(default=False)
    # The server process whose event log derived it ("" when a request wrote it), so each
    # recorder reads from the log only the events it did not take from its own process.
    origin = models.CharField(max_length=32, blank=True, default="")
    acknowledged_at = models.DateTimeField(null=True, blank=True)
    acknowledged_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    cleared_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-time", "-id"]
        indexes = [
            models.Index(fields=["building", "time"]),
            models.Index(fields=["robot", "time"]),
            models.Index(fields=["alert", "acknowledged_at"]),
        ]

    def __str__(self) -> str:
        return f"{self.time:%Y-%m-%d %H:%M:%S} {self.kind}: {self.message}"
