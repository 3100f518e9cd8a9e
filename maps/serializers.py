"""Wire shapes of the map store API; the rules behind them live in ``services`` and ``domain``."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.contrib.auth.models import User
from django.db.models import Q, QuerySet
from django.urls import reverse
from rest_framework import serializers

from . import services
from .access import ROLE_NAMES, buildings_for, global_role, role_named
from .domain import tagart
from .domain.mapfile import LoadedMap, load_map_archive, load_map_upload
from .domain.planning import PoseRefused
from .domain.tagart import marker_id_limit
from .domain.versions import map_ref
from .exceptions import TagPayloadError
from .models import Building, EnvironmentalTag, Membership, ParkingSpot, SubMap, SubMapVersion


def _requester(field: serializers.Field[Any, Any, Any, Any]) -> Any:
    request = field.context.get("request")
    return getattr(request, "user", None)


class KnownUser(serializers.SlugRelatedField[User]):
    """A username among the users the requester may know of: those sharing one of their
    buildings, and those of no building yet (all for a superuser). A browsable form lists
    no other tenant's users, and their names read as unknown."""

    def get_queryset(self) -> QuerySet[User]:
        user = _requester(self)
        if user is not None and user.is_superuser:
            return User.objects.all()
        mine = buildings_for(user) if user is not None else Building.objects.none()
        return User.objects.filter(Q(buildings__in=mine) | Q(buildings__isnull=True)).distinct()


class VisibleBuilding(serializers.SlugRelatedField[Building]):
    """A building code among the buildings the requester sees."""

    def get_queryset(self) -> QuerySet[Building]:
        user = _requester(self)
        return buildings_for(user) if user is not None else Building.objects.none()


class BuildingSerializer(serializers.ModelSerializer[Building]):
    members = KnownUser(slug_field="username", many=True, required=False)

    class Meta:
        model = Building
        fields = [
            "code",
            "name",
            "zip_code",
            "address",
            "marker_dictionary",
            "fleet_rule",
            "members",
        ]

    def validate_marker_dictionary(self, value: str) -> str:
        try:
            marker_id_limit(value)
        except TagPayloadError as exc:
            raise serializers.ValidationError(str(exc)) from None
        return value


class MembershipSerializer(serializers.ModelSerializer[Membership]):
    """A member of a building and their role there (the role of their group when the
    membership names none, and when ``role`` is left out on adding them)."""

    username = KnownUser(source="user", slug_field="username")
    role = serializers.ChoiceField(choices=["admin", "operator", "viewer"], required=False)

    class Meta:
        model = Membership
        fields = ["username", "role"]

    def get_fields(self) -> dict[str, Any]:
        fields = super().get_fields()
        if isinstance(self.instance, Membership):
            fields["username"].read_only = True  # a membership changes role, not person
        return fields

    def to_representation(self, instance: Membership) -> dict[str, Any]:
        role = role_named(instance.role) or global_role(instance.user)
        return {"username": instance.user.username, "role": ROLE_NAMES.get(role, "")}

    def validate(self, attrs: dict[str, Any]) -> dict[str, Any]:
        building = self.context.get("building")
        user = attrs.get("user")
        taken = building is not None and building.memberships.filter(user=user).exists()
        if user is not None and taken:
            raise serializers.ValidationError({"username": ["Already a member of this building."]})
        if user is not None and "role" not in attrs:
            attrs["role"] = ROLE_NAMES.get(global_role(user), "viewer")
        return attrs


class SubMapSerializer(serializers.ModelSerializer[SubMap]):
    """A sub-map. Its ``version`` is the number people see as ``v<n>`` everywhere;
    ``content_hash`` is the digest of its map file (what a cache compares)."""

    map_id = serializers.CharField(read_only=True)
    version = serializers.IntegerField(source="revision", read_only=True)
    content_hash = serializers.CharField(source="version", read_only=True)
    origin = serializers.SerializerMethodField()
    links = serializers.SerializerMethodField()

    class Meta:
        model = SubMap
        fields = [
            "code",
            "name",
            "map_id",
            "image_name",
            "width",
            "height",
            "resolution",
            "origin",
            "occupied_thresh",
            "free_thresh",
            "negate",
            "mode",
            "version",
            "content_hash",
            "node_x",
            "node_y",
            "updated",
            "links",
        ]

    def get_origin(self, submap: SubMap) -> list[float]:
        return [submap.origin_x, submap.origin_y, submap.origin_yaw]

    def get_links(self, submap: SubMap) -> dict[str, str]:
        args = [submap.building.code, submap.code]
        names = ["image", "grid", "export", "bundle"]
        links = {name: reverse(f"submap-{name}", args=args) for name in names}
        return {**links, "versions": reverse("version-list", args=args)}


class SubMapUploadSerializer(serializers.Serializer[Any]):
    """A map_server pair as ``image`` + ``yaml`` files, or a zip of both as ``archive``.

    ``replace`` lets the upload replace the map of an existing code; ``dry_run`` checks
    and converts the upload as storing it would, stores nothing and answers a preview
    (then ``code`` may be left out).
    """

    code = serializers.RegexField(r"^[A-Za-z][A-Za-z0-9_]*$", max_length=40, required=False)
    name = serializers.CharField(max_length=200, required=False, allow_blank=True)
    image = serializers.FileField(required=False)
    yaml = serializers.FileField(required=False)
    archive = serializers.FileField(required=False)
    node_x = serializers.FloatField(required=False)
    node_y = serializers.FloatField(required=False)
    replace = serializers.BooleanField(
        default=False, help_text="Replace the map of an existing code (else 409)."
    )
    dry_run = serializers.BooleanField(
        default=False, help_text="Check and preview the upload; store nothing."
    )
    note = serializers.CharField(
        max_length=500, required=False, allow_blank=True, help_text="Why: kept in the history"
    )

    def validate(self, attrs: dict[str, Any]) -> dict[str, Any]:
        if "code" not in attrs and not attrs["dry_run"]:
            raise serializers.ValidationError({"code": ["This field is required."]})
        has_pair = "image" in attrs or "yaml" in attrs
        if "archive" in attrs and has_pair:
            raise serializers.ValidationError({"archive": ["Send an archive or a pair, not both."]})
        if "archive" not in attrs:
            missing = [f for f in ("image", "yaml") if f not in attrs]
            if missing:
                raise serializers.ValidationError({f: ["This file is required."] for f in missing})
        return attrs

    def load(self) -> LoadedMap:
        """Decode and convert the upload; raises MapFileError naming the field at fault."""
        data = self.validated_data
        limit = settings.CLOUDNAV_MAX_MAP_PIXELS
        if "archive" in data:
            return load_map_archive(
                data["archive"].read(), limit, settings.CLOUDNAV_MAX_UPLOAD_BYTES
            )
        image = data["image"]
        return load_map_upload(data["yaml"].read(), {image.name: image.read()}, limit)


class SubMapUpdateSerializer(serializers.Serializer[Any]):
    """Metadata edits; cross-field rules (thresholds) are checked by the map file domain."""

    name = serializers.CharField(max_length=200, required=False, allow_blank=True)
    resolution = serializers.FloatField(required=False)
    origin = serializers.ListField(
        child=serializers.FloatField(), min_length=3, max_length=3, required=False
    )
    occupied_thresh = serializers.FloatField(required=False)
    free_thresh = serializers.FloatField(required=False)
    negate = serializers.BooleanField(required=False)
    mode = serializers.ChoiceField(["trinary", "scale", "raw"], required=False)
    node_x = serializers.FloatField(required=False)
    node_y = serializers.FloatField(required=False)


class TagSerializer(serializers.ModelSerializer[EnvironmentalTag]):
    building = VisibleBuilding(slug_field="code")
    submap = serializers.CharField(source="submap.code")
    links_to = serializers.CharField(source="links_to.code")
    map_id = serializers.CharField(source="submap.map_id", read_only=True)
    payload = serializers.SerializerMethodField()

    class Meta:
        model = EnvironmentalTag
        fields = [
            "id",
            "building",
            "submap",
            "map_id",
            "marker_id",
            "x",
            "y",
            "yaw",
            "size",
            "links_to",
            "payload",
        ]
        # Marker uniqueness is checked in validate(), so the error names the marker_id field.
        validators: list[Any] = []
        extra_kwargs = {"size": {"min_value": tagart.MIN_SIZE, "max_value": tagart.MAX_SIZE}}

    def get_payload(self, tag: EnvironmentalTag) -> str:
        return services.tag_art(tag).payload

    def validate(self, attrs: dict[str, Any]) -> dict[str, Any]:
        building: Building = attrs.get("building") or self.instance.building  # type: ignore[union-attr]
        if self.instance is not None and building != self.instance.building:
            raise serializers.ValidationError(
                {"building": ["A tag cannot move to another building."]}
            )
        for field in ("submap", "links_to"):
            if field in attrs:
                attrs[field] = self._submap_in(building, field, attrs[field]["code"])
        self._check_marker(building, attrs)
        self._check_payload(building, attrs)
        return attrs

    def _submap_in(self, building: Building, field: str, code: str) -> SubMap:
        submap = building.submaps.defer("image").filter(code=code).first()
        if submap is None:
            raise serializers.ValidationError(
                {field: [f"'{code}' is not a sub-map of {building}."]}
            )
        return submap

    def _check_marker(self, building: Building, attrs: dict[str, Any]) -> None:
        marker_id = attrs.get("marker_id")
        if marker_id is None:
            return
        limit = marker_id_limit(building.marker_dictionary)
        if marker_id >= limit:
            raise serializers.ValidationError(
                {"marker_id": [f"{building.marker_dictionary} has ids 0 to {limit - 1}."]}
            )
        clash = building.tags.filter(marker_id=marker_id)
        if self.instance is not None:
            clash = clash.exclude(pk=self.instance.pk)
        if clash.exists():
            raise serializers.ValidationError(
                {"marker_id": [f"Marker {marker_id} is already used in {building}."]}
            )

    def _check_payload(self, building: Building, attrs: dict[str, Any]) -> None:
        links_to = attrs.get("links_to") or getattr(self.instance, "links_to", None)
        if links_to is None:
            return
        try:
            services.check_tag_payload(building, links_to)
        except TagPayloadError as exc:
            raise serializers.ValidationError({"links_to": [str(exc)]}) from None


class ParkingSpotSerializer(serializers.ModelSerializer[ParkingSpot]):
    """A parking spot of the building in the URL (``context["building"]``): its sub-map by
    code, and a pose a robot could stand at there (``maps.domain.planning.GoalCheck``)."""

    map = serializers.CharField(source="submap.code")
    map_id = serializers.CharField(source="submap.map_id", read_only=True)
    x = serializers.FloatField(min_value=-1e6, max_value=1e6)
    y = serializers.FloatField(min_value=-1e6, max_value=1e6)
    yaw = serializers.FloatField(min_value=-1e6, max_value=1e6, default=0.0)

    class Meta:
        model = ParkingSpot
        fields = ["id", "name", "map", "map_id", "x", "y", "yaw"]
        validators: list[Any] = []  # the name's uniqueness: validate(), naming the field

    def validate(self, attrs: dict[str, Any]) -> dict[str, Any]:
        building: Building = self.context["building"]
        spot = self.instance
        if "submap" in attrs:
            attrs["submap"] = self._submap_in(building, attrs["submap"]["code"])
        submap = attrs.get("submap") or (spot.submap if spot is not None else None)
        x, y = attrs.get("x", getattr(spot, "x", None)), attrs.get("y", getattr(spot, "y", None))
        if submap is not None and x is not None and y is not None:
            self._check_standable(submap, x, y)
        if "name" in attrs:
            self._check_name(building, attrs["name"])
        return attrs

    @staticmethod
    def _submap_in(building: Building, code: str) -> SubMap:
        submap = building.submaps.defer("image").filter(code=code).first()
        if submap is None:
            raise serializers.ValidationError(
                {"map": [f"'{code}' is not a sub-map of {building}."]}
            )
        return submap

    @staticmethod
    def _check_standable(submap: SubMap, x: float, y: float) -> None:
        try:
            services.goal_check_of(submap).check((x, y), "parking spot", tolerance=0.0)
        except PoseRefused as refused:
            raise serializers.ValidationError({"x": [str(refused)], "y": [str(refused)]}) from None

    def _check_name(self, building: Building, name: str) -> None:
        clash = building.parking_spots.filter(name=name)
        if self.instance is not None:
            clash = clash.exclude(pk=self.instance.pk)
        if clash.exists():
            raise serializers.ValidationError({"name": [f"{building} has a spot named {name!r}."]})


class VersionSerializer(serializers.ModelSerializer[SubMapVersion]):
    """One version of a sub-map, without its image (see ``links``): ``number`` is the ``n``
    of ``v<n>``, ``content_hash`` the digest of its map file."""

    author: serializers.SlugRelatedField[Any] = serializers.SlugRelatedField(
        slug_field="username", read_only=True
    )
    map_ref = serializers.SerializerMethodField()
    content_hash = serializers.CharField(source="version", read_only=True)
    origin = serializers.SerializerMethodField()
    links = serializers.SerializerMethodField()

    class Meta:
        model = SubMapVersion
        fields = [
            "number",
            "map_ref",
            "reason",
            "note",
            "author",
            "created",
            "based_on",
            "content_hash",
            "image_name",
            "width",
            "height",
            "resolution",
            "origin",
            "links",
        ]

    def get_map_ref(self, version: SubMapVersion) -> str:
        return map_ref(version.submap.map_id, version.number)

    def get_origin(self, version: SubMapVersion) -> list[float]:
        return [version.origin_x, version.origin_y, version.origin_yaw]

    def get_links(self, version: SubMapVersion) -> dict[str, str]:
        args = [version.submap.building.code, version.submap.code, version.number]
        names = ["image", "grid", "rollback"]
        return {name: reverse(f"version-{name}", args=args) for name in names}


class VersionComparisonSerializer(serializers.Serializer[Any]):
    """The query (``from``, ``to``: version numbers) and answer of a comparison."""

    to = serializers.IntegerField(min_value=1)
    added = serializers.IntegerField(read_only=True)
    removed = serializers.IntegerField(read_only=True)
    unknown_changed = serializers.IntegerField(read_only=True)
    compared = serializers.IntegerField(read_only=True)
    truncated = serializers.BooleanField(read_only=True)
    cells = serializers.DictField(read_only=True)

    def get_fields(self) -> dict[str, Any]:
        fields = super().get_fields()
        fields["from"] = serializers.IntegerField(min_value=1)  # a keyword in Python
        return fields

    @classmethod
    def numbers(cls, query: Any) -> dict[str, int]:
        """The version numbers ``from`` and ``to`` of a query; raises ValidationError."""
        parsed = cls(data=query)
        parsed.is_valid(raise_exception=True)
        return {"from": parsed.validated_data["from"], "to": parsed.validated_data["to"]}


class TopologyNodeSerializer(serializers.Serializer[Any]):
    code = serializers.CharField()
    name = serializers.CharField(read_only=True)
    x = serializers.FloatField()
    y = serializers.FloatField()


class TopologyEdgeSerializer(serializers.Serializer[Any]):
    a = serializers.CharField()
    b = serializers.CharField()
    cost = serializers.FloatField()


class TopologySerializer(serializers.Serializer[Any]):
    nodes = TopologyNodeSerializer(many=True, required=False)
    edges = TopologyEdgeSerializer(many=True)
    crossings = serializers.ListField(
        child=serializers.DictField(),
        read_only=True,
        help_text="Tags that let a robot cross: {from, to, marker_id}; routes go no other way.",
    )


class RouteStepSerializer(serializers.Serializer[Any]):
    map = serializers.CharField()
    map_id = serializers.CharField()
    tag = serializers.DictField(allow_null=True)


class RouteSerializer(serializers.Serializer[Any]):
    building = serializers.CharField()
    steps = RouteStepSerializer(many=True)


class CoverageSerializer(serializers.Serializer[Any]):
    valid = serializers.BooleanField()
    uncrossable_edges = serializers.ListField(child=serializers.DictField())
    dangling_tags = serializers.ListField(child=serializers.DictField())
