"""The paper's entities B (Building) and M (SubMap), with tags and the topology graph."""

from __future__ import annotations

from django.conf import settings
from django.core.validators import MinValueValidator, RegexValidator
from django.db import models

from cloudnav_core.grid import FREE_THRESH, OCCUPIED_THRESH

from .domain.reservations import FleetRule
from .domain.versions import Reason, map_ref

code_validator = RegexValidator(
    r"^[A-Za-z][A-Za-z0-9_]*$",
    "Use letters, digits and underscores, starting with a letter.",
)


class Building(models.Model):
    """A building, its people and its topology graph (nodes: sub-maps, edges: crossings)."""

    code = models.CharField(max_length=40, unique=True, validators=[code_validator])
    name = models.CharField(max_length=200)
    zip_code = models.CharField(max_length=20, blank=True)
    address = models.CharField(max_length=300, blank=True)
    marker_dictionary = models.CharField(max_length=40, default="DICT_APRILTAG_36h11")
    # What a goal gets whose spot another robot holds (``maps.domain.reservations``).
    fleet_rule = models.CharField(
        max_length=10,
        choices=[(r.value, r.value) for r in FleetRule],
        default=FleetRule.MOVE.value,
    )
    members = models.ManyToManyField(
        settings.AUTH_USER_MODEL, blank=True, related_name="buildings", through="Membership"
    )
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["code"]

    def __str__(self) -> str:
        return self.code


class Membership(models.Model):
    """A person's membership of a building and their role there.

    An empty role (a membership added without one, by the Django admin or a script) is
    the role of the person's group."""

    ROLES = [("admin", "admin"), ("operator", "operator"), ("viewer", "viewer")]

    building = models.ForeignKey(Building, models.CASCADE, related_name="memberships")
    user = models.ForeignKey(settings.AUTH_USER_MODEL, models.CASCADE, related_name="memberships")
    role = models.CharField(max_length=10, choices=ROLES, blank=True, default="")

    class Meta:
        db_table = "maps_building_members"  # the table of the plain many-to-many it replaced
        unique_together = [("building", "user")]

    def __str__(self) -> str:
        return f"{self.user} in {self.building} ({self.role or 'group role'})"


class MapFile(models.Model):
    """A map_server pair: the image as uploaded and its YAML metadata, with a content
    version (hash) that changes whenever either changes."""

    MODES = [("trinary", "trinary"), ("scale", "scale"), ("raw", "raw")]

    image = models.BinaryField()
    image_name = models.CharField(max_length=200)
    width = models.PositiveIntegerField()
    height = models.PositiveIntegerField()
    resolution = models.FloatField()
    origin_x = models.FloatField(default=0.0)
    origin_y = models.FloatField(default=0.0)
    origin_yaw = models.FloatField(default=0.0)
    occupied_thresh = models.FloatField(default=OCCUPIED_THRESH)
    free_thresh = models.FloatField(default=FREE_THRESH)
    negate = models.BooleanField(default=False)
    mode = models.CharField(max_length=10, choices=MODES, default="trinary")
    version = models.CharField(max_length=64, editable=False)

    class Meta:
        abstract = True


class SubMap(MapFile):
    """One ROS map_server map of part of a building; ``building/code`` is its Map ID.

    Its map file is a copy of its current version's (``revision``, see SubMapVersion)."""

    building = models.ForeignKey(Building, models.CASCADE, related_name="submaps")
    code = models.CharField(max_length=40, validators=[code_validator])
    name = models.CharField(max_length=200, blank=True)
    revision = models.PositiveIntegerField(default=1, editable=False)
    # Where the node is drawn in the topology editor, in the editor's own units.
    node_x = models.FloatField(default=0.0)
    node_y = models.FloatField(default=0.0)
    updated = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["building", "code"]
        constraints = [
            models.UniqueConstraint(fields=["building", "code"], name="submap_unique_code")
        ]

    def __str__(self) -> str:
        return self.map_id

    @property
    def map_id(self) -> str:
        return f"{self.building.code}/{self.code}"


class SubMapVersion(MapFile):
    """One version of a sub-map: its map_server pair as it was made, who made it, when and
    why. Versions are numbered from 1 per sub-map and never change once made; the sub-map
    holds a copy of its current one (``SubMap.revision``)."""

    REASONS = [(reason.value, reason.value) for reason in Reason]

    submap = models.ForeignKey(SubMap, models.CASCADE, related_name="versions")
    number = models.PositiveIntegerField()
    reason = models.CharField(max_length=16, choices=REASONS)
    note = models.CharField(max_length=500, blank=True)
    author = models.ForeignKey(
        settings.AUTH_USER_MODEL, models.SET_NULL, null=True, blank=True, related_name="+"
    )
    created = models.DateTimeField(auto_now_add=True)
    # The version this one restores (rollback) or was built on (mapping, accepted change).
    based_on = models.PositiveIntegerField(null=True, blank=True)

    class Meta:
        ordering = ["submap", "-number"]
        constraints = [
            models.UniqueConstraint(fields=["submap", "number"], name="version_unique_number")
        ]

    def __str__(self) -> str:
        return map_ref(self.submap.map_id, self.number)


class TopologyEdge(models.Model):
    """An undirected crossing between two sub-maps; ``a`` sorts before ``b`` by id."""

    building = models.ForeignKey(Building, models.CASCADE, related_name="edges")
    a = models.ForeignKey(SubMap, models.CASCADE, related_name="+")
    b = models.ForeignKey(SubMap, models.CASCADE, related_name="+")
    cost = models.FloatField(validators=[MinValueValidator(0.0)])

    class Meta:
        ordering = ["building", "a", "b"]
        constraints = [
            models.UniqueConstraint(fields=["a", "b"], name="edge_unique_pair"),
            models.CheckConstraint(condition=~models.Q(a=models.F("b")), name="edge_no_loop"),
        ]

    def __str__(self) -> str:
        return f"{self.a.code} - {self.b.code} ({self.cost:g})"


class EnvironmentalTag(models.Model):
    """A printed QR code + fiducial marker standing in a sub-map, leading to another."""

    building = models.ForeignKey(Building, models.CASCADE, related_name="tags")
    submap = models.ForeignKey(SubMap, models.CASCADE, related_name="tags")
    marker_id = models.PositiveIntegerField()
    x = models.FloatField()
    y = models.FloatField()
    yaw = models.FloatField()
    size = models.FloatField(default=0.06, validators=[MinValueValidator(0.01)])
    links_to = models.ForeignKey(SubMap, models.CASCADE, related_name="incoming_tags")

    class Meta:
        ordering = ["building", "marker_id"]
        constraints = [
            models.UniqueConstraint(fields=["building", "marker_id"], name="tag_unique_marker")
        ]

    def __str__(self) -> str:
        return f"tag {self.marker_id} in {self.submap}"


class ParkingSpot(models.Model):
    """A named place in a sub-map where a robot waits out of the others' way: a robot
    that finished its goal on a spot others need is sent to the nearest free one
    (``maps.domain.reservations.Reservations.parking_for``)."""

    building = models.ForeignKey(Building, models.CASCADE, related_name="parking_spots")
    submap = models.ForeignKey(SubMap, models.CASCADE, related_name="parking_spots")
    name = models.CharField(max_length=60)
    x = models.FloatField()
    y = models.FloatField()
    yaw = models.FloatField(default=0.0)

    class Meta:
        ordering = ["building", "name"]
        constraints = [
            models.UniqueConstraint(fields=["building", "name"], name="parking_unique_name")
        ]

    def __str__(self) -> str:
        return f"parking {self.name} in {self.submap}"


class MappingSession(models.Model):
    """A robot building a sub-map in the cloud: a new one (``code`` not yet a sub-map) or
    an update of ``submap`` made on its version ``based_on``.

    The server process the robot is connected to runs its SLAM and writes the map so far
    here every few seconds (``grid_pgm``: a map_saver PGM with its origin and resolution),
    with the corrected path and the keyframes it needs to resume. A ``laser`` session maps
    from the robot's scans, a ``visual`` one from its camera's image and depth."""

    RUNNING, INTERRUPTED, FINISHED, PUBLISHED, DISCARDED = (
        "running",
        "interrupted",
        "finished",
        "published",
        "discarded",
    )
    STATES = [(s, s) for s in (RUNNING, INTERRUPTED, FINISHED, PUBLISHED, DISCARDED)]
    OPEN = (RUNNING, INTERRUPTED)
    LASER, VISUAL = "laser", "visual"
    KINDS = [(LASER, "laser: scans and odometry"), (VISUAL, "visual: an RGB-D camera")]

    robot = models.ForeignKey("robots.Robot", models.CASCADE, related_name="mapping_sessions")
    kind = models.CharField(max_length=8, choices=KINDS, default=LASER)
    building = models.ForeignKey(Building, models.CASCADE, related_name="mapping_sessions")
    code = models.CharField(max_length=40, validators=[code_validator])
    submap = models.ForeignKey(
        SubMap, models.SET_NULL, null=True, blank=True, related_name="mapping_sessions"
    )
    based_on = models.PositiveIntegerField(null=True, blank=True)
    state = models.CharField(max_length=12, choices=STATES, default=RUNNING)
    reason = models.CharField(max_length=300, blank=True)  # why it stopped, in words
    started_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, models.SET_NULL, null=True, blank=True, related_name="+"
    )
    created = models.DateTimeField(auto_now_add=True)
    updated = models.DateTimeField(auto_now=True)
    start_x = models.FloatField(default=0.0)
    start_y = models.FloatField(default=0.0)
    start_yaw = models.FloatField(default=0.0)
    grid_pgm = models.BinaryField(default=b"", blank=True)
    origin_x = models.FloatField(default=0.0)
    origin_y = models.FloatField(default=0.0)
    resolution = models.FloatField(default=0.05)
    snapshot = models.PositiveIntegerField(default=0)  # counts the maps written
    path = models.JSONField(default=list, blank=True)
    stats = models.JSONField(default=dict, blank=True)
    keyframes = models.BinaryField(default=b"", blank=True)

    class Meta:
        ordering = ["-created"]
        constraints = [
            models.UniqueConstraint(
                fields=["robot"],
                condition=models.Q(state__in=["running", "interrupted"]),
                name="one_open_mapping_session_per_robot",
            )
        ]

    def __str__(self) -> str:
        return f"mapping {self.building.code}/{self.code} by {self.robot} ({self.state})"


class ChangeProposal(models.Model):
    """A change to a sub-map that the fleet's lasers back: cells that became occupied
    (``added``) and free (``removed``), as ``[row, col]`` of the version ``based_on``,
    with the passes and the distinct robots that saw each (``added_passes``,
    ``removed_passes``, ``added_robots``, ``removed_robots``; 0 for a cell an admin
    painted) and the robots behind the whole (``robots``). An admin's edit may also make
    cells ``unknown``; an ``edited`` proposal is no longer rewritten by the fleet's
    evidence."""

    OPEN, ACCEPTED, REJECTED = "open", "accepted", "rejected"
    STATES = [(s, s) for s in (OPEN, ACCEPTED, REJECTED)]

    submap = models.ForeignKey(SubMap, models.CASCADE, related_name="change_proposals")
    based_on = models.PositiveIntegerField()
    state = models.CharField(max_length=10, choices=STATES, default=OPEN)
    added = models.JSONField(default=list)
    removed = models.JSONField(default=list)
    added_passes = models.JSONField(default=list)
    removed_passes = models.JSONField(default=list)
    added_robots = models.JSONField(default=list)
    removed_robots = models.JSONField(default=list)
    unknown = models.JSONField(default=list)
    edited = models.BooleanField(default=False)
    passes = models.PositiveIntegerField(default=0)
    robots = models.PositiveIntegerField(default=0)
    scans = models.PositiveIntegerField(default=0)
    created = models.DateTimeField(auto_now_add=True)
    updated = models.DateTimeField(auto_now=True)
    decided_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, models.SET_NULL, null=True, blank=True, related_name="+"
    )
    version = models.PositiveIntegerField(null=True, blank=True)  # made by accepting it

    class Meta:
        ordering = ["-updated"]
        constraints = [
            models.UniqueConstraint(
                fields=["submap", "based_on"],
                condition=models.Q(state="open"),
                name="one_open_proposal_per_version",
            )
        ]

    def __str__(self) -> str:
        return f"change to {self.submap} v{self.based_on} ({self.state})"


class Keyframe(models.Model):
    """A camera keyframe of a sub-map's visual map: where the robot stood, and the file
    (``CLOUDNAV_KEYFRAME_DIR``/``path``) holding its features, 3D points and words."""

    submap = models.ForeignKey(SubMap, models.CASCADE, related_name="keyframes")
    robot = models.CharField(max_length=100, blank=True)
    x = models.FloatField()
    y = models.FloatField()
    yaw = models.FloatField()
    points = models.PositiveIntegerField()
    path = models.CharField(max_length=300)
    size = models.PositiveIntegerField()
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["submap", "id"]

    def __str__(self) -> str:
        return f"keyframe {self.pk} of {self.submap}"
