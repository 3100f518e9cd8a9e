"""The paper's entities B (Building) and M (SubMap), with tags and the topology graph."""

from __future__ import annotations

from django.conf import settings
from django.core.validators import MinValueValidator, RegexValidator
from django.db import models

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
    members = models.ManyToManyField(settings.AUTH_USER_MODEL, blank=True, related_name="buildings")
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["code"]

    def __str__(self) -> str:
        return self.code


class SubMap(models.Model):
    """One ROS map_server map of part of a building; ``building/code`` is its Map ID."""

    MODES = [("trinary", "trinary"), ("scale", "scale"), ("raw", "raw")]

    building = models.ForeignKey(Building, models.CASCADE, related_name="submaps")
    code = models.CharField(max_length=40, validators=[code_validator])
    name = models.CharField(max_length=200, blank=True)
    image = models.BinaryField()
    image_name = models.CharField(max_length=200)
    width = models.PositiveIntegerField()
    height = models.PositiveIntegerField()
    resolution = models.FloatField()
    origin_x = models.FloatField(default=0.0)
    origin_y = models.FloatField(default=0.0)
    origin_yaw = models.FloatField(default=0.0)
    occupied_thresh = models.FloatField(default=0.65)
    free_thresh = models.FloatField(default=0.196)
    negate = models.BooleanField(default=False)
    mode = models.CharField(max_length=10, choices=MODES, default="trinary")
    version = models.CharField(max_length=64, editable=False)
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
