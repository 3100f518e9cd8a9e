"""The paper's entity R: registered robots and their credentials."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from django.core.validators import MinValueValidator, RegexValidator
from django.db import models

from maps.models import Building

ros_name_validator = RegexValidator(
    r"^[A-Za-z][A-Za-z0-9_]*$",
    "A robot name is a ROS name segment: a letter, then letters, digits or underscores.",
)


class Robot(models.Model):
    """A registered robot. Its token is shown once; only its SHA-256 is stored."""

    name = models.CharField(max_length=64, unique=True, validators=[ros_name_validator])
    description = models.CharField(max_length=300, blank=True)
    buildings = models.ManyToManyField(Building, blank=True, related_name="robots")
    token_hash = models.CharField(max_length=64, unique=True, editable=False)
    token_rotated = models.DateTimeField(auto_now_add=True)
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["name"]

    def __str__(self) -> str:
        return self.name

    def online_state(self) -> RobotState | None:
        """Its fleet state while it is connected to a live server process, else None."""
        state = RobotState.objects.filter(robot=self).first()
        return state if state is not None and is_online(state) else None


class RobotState(models.Model):
    """A robot's last known fleet state, written at a throttled rate by the rosbridge server."""

    robot = models.OneToOneField(Robot, models.CASCADE, primary_key=True, related_name="state")
    online = models.BooleanField(default=False)
    map_id = models.CharField(max_length=100, blank=True)
    # The version of ``map_id`` the robot holds, as it said on its ``map_id`` topic.
    map_version = models.PositiveIntegerField(null=True, blank=True)
    x = models.FloatField(null=True, blank=True)
    y = models.FloatField(null=True, blank=True)
    yaw = models.FloatField(null=True, blank=True)
    last_seen = models.DateTimeField(null=True, blank=True)

    def __str__(self) -> str:
        return f"{self.robot.name} ({'online' if self.online else 'offline'})"


class Mission(models.Model):
    """A list of goals (``waypoints``: ``{"map", "x", "y", "yaw"}``, any sub-maps of
    ``building``) a robot drives to in turn, once or round and round (a patrol).

    The server that serves the robot sends each goal and moves on when the robot reports
    it reached it (``telemetry.missions``); ``sent`` is the index of the goal sent last
    (-1: none since the last start or change). A robot has at most one active mission.
    A waypoint not reached ``time_limit`` seconds after its goal was sent (0: no limit)
    is skipped or pauses the mission, as ``on_timeout`` says.
    """

    class Mode(models.TextChoices):
        ONCE = "once"
        PATROL = "patrol"

    class OnTimeout(models.TextChoices):
        SKIP = "skip"
        PAUSE = "pause"

    class State(models.TextChoices):
        RUNNING = "running"
        PAUSED = "paused"
        DONE = "done"
        CANCELLED = "cancelled"

    ACTIVE = (State.RUNNING, State.PAUSED)
    NAME_LENGTH = 100

    building = models.ForeignKey(Building, models.CASCADE, related_name="missions")
    robot = models.ForeignKey(Robot, models.CASCADE, related_name="missions")
    name = models.CharField(max_length=NAME_LENGTH, blank=True)
    waypoints = models.JSONField()
    mode = models.CharField(max_length=10, choices=Mode.choices, default=Mode.ONCE)
    state = models.CharField(max_length=10, choices=State.choices, default=State.RUNNING)
    index = models.PositiveIntegerField(default=0)
    laps = models.PositiveIntegerField(default=0)
    sent = models.IntegerField(default=-1)
    time_limit = models.FloatField(default=300.0, validators=[MinValueValidator(0.0)])
    on_timeout = models.CharField(max_length=10, choices=OnTimeout.choices, default=OnTimeout.PAUSE)
    note = models.CharField(max_length=300, blank=True)
    created_by = models.CharField(max_length=150, blank=True)
    created = models.DateTimeField(auto_now_add=True)
    updated = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["-created"]
        indexes = [models.Index(fields=["robot", "state"])]

    def __str__(self) -> str:
        return f"{self.robot}: {self.name or 'mission'} ({self.state})"


# A robot whose row is older than this is shown offline whatever the row says: the process
# that served it stopped without saying goodbye (the rosbridge server writes connected
# robots every ``telemetry.rosbridge.fleet_state.HEARTBEAT``).
STALE_AFTER = timedelta(seconds=30)


def is_online(state: RobotState, now: datetime | None = None) -> bool:
    """True if the robot is connected to a live server process."""
    now = now or datetime.now(UTC)
    return bool(state.online and state.last_seen and now - state.last_seen < STALE_AFTER)
