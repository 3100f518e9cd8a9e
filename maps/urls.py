"""Map store routes under /api/."""

from __future__ import annotations

from django.urls import path, re_path

from .mapping import views as mapping
from .views.buildings import BuildingDetail, BuildingList
from .views.map_versions import (
    VersionComparison,
    VersionDetail,
    VersionGrid,
    VersionImage,
    VersionList,
    VersionRollback,
)
from .views.members import MemberDetail, MemberList
from .views.parking import ParkingSpotDetail, ParkingSpotList
from .views.submaps import (
    SubMapBundle,
    SubMapDetail,
    SubMapExport,
    SubMapGrid,
    SubMapImage,
    SubMapList,
)
from .views.tags import BuildingTagSheet, TagDetail, TagList, TagPrint
from .views.topology import Route, Topology, TopologyValidation
from .views.visual_map import Relocalise, SubMapKeyframes

building = "buildings/<slug:building>"
submap = f"{building}/maps/<slug:map>"
version = f"{submap}/versions/<int:number>"

urlpatterns = [
    path("buildings/", BuildingList.as_view(), name="building-list"),
    path(f"{building}/", BuildingDetail.as_view(), name="building-detail"),
    path(f"{building}/members/", MemberList.as_view(), name="member-list"),
    path(f"{building}/members/<str:username>/", MemberDetail.as_view(), name="member-detail"),
    path(f"{building}/maps/", SubMapList.as_view(), name="submap-list"),
    path(f"{submap}/", SubMapDetail.as_view(), name="submap-detail"),
    path(f"{submap}/image", SubMapImage.as_view(), name="submap-image"),
    path(f"{submap}/grid", SubMapGrid.as_view(), name="submap-grid"),
    path(f"{submap}/export", SubMapExport.as_view(), name="submap-export"),
    path(f"{submap}/bundle", SubMapBundle.as_view(), name="submap-bundle"),
    path(f"{submap}/versions/", VersionList.as_view(), name="version-list"),
    path(f"{submap}/versions/compare", VersionComparison.as_view(), name="version-compare"),
    path(f"{version}/", VersionDetail.as_view(), name="version-detail"),
    path(f"{version}/image", VersionImage.as_view(), name="version-image"),
    path(f"{version}/grid", VersionGrid.as_view(), name="version-grid"),
    re_path(
        r"^buildings/(?P<building>[-\w]+)/maps/(?P<map>[-\w]+)/versions/(?P<number>\d+)/"
        r"(?P<name>cloud\.ply|octomap\.bt)$",
        mapping.VersionMap3D.as_view(),
        name="version-map3d",
    ),
    path(f"{version}/rollback", VersionRollback.as_view(), name="version-rollback"),
    path(f"{submap}/changes/", mapping.ProposalList.as_view(), name="change-list"),
    path(f"{submap}/changes/<int:pk>/", mapping.ProposalDetail.as_view(), name="change-detail"),
    re_path(
        r"^buildings/(?P<building>[-\w]+)/maps/(?P<map>[-\w]+)/changes/(?P<pk>\d+)/"
        r"(?P<decision>accept|reject)$",
        mapping.ProposalDecision.as_view(),
        name="change-decision",
    ),
    path(f"{submap}/keyframes", SubMapKeyframes.as_view(), name="submap-keyframes"),
    path("relocalise", Relocalise.as_view(), name="relocalise"),
    path(f"{building}/topology", Topology.as_view(), name="topology"),
    path(f"{building}/parking/", ParkingSpotList.as_view(), name="parking-list"),
    path(f"{building}/parking/<int:pk>/", ParkingSpotDetail.as_view(), name="parking-detail"),
    path(
        f"{building}/topology/validation",
        TopologyValidation.as_view(),
        name="topology-validation",
    ),
    path(f"{building}/route", Route.as_view(), name="route"),
    path(f"{building}/tags/print.pdf", BuildingTagSheet.as_view(), name="tag-sheet"),
    path("mapping/sessions/", mapping.SessionList.as_view(), name="mapping-list"),
    path("mapping/sessions/<int:pk>/", mapping.SessionDetail.as_view(), name="mapping-detail"),
    path("mapping/sessions/<int:pk>/grid", mapping.SessionGrid.as_view(), name="mapping-grid"),
    re_path(
        r"^mapping/sessions/(?P<pk>\d+)/(?P<name>cloud\.ply|octomap\.bt)$",
        mapping.SessionMap3D.as_view(),
        name="mapping-map3d",
    ),
    path(
        "mapping/sessions/<int:pk>/points", mapping.SessionPoints.as_view(), name="mapping-points"
    ),
    path(
        "mapping/sessions/<int:pk>/candidate.zip",
        mapping.SessionCandidate.as_view(),
        name="mapping-candidate",
    ),
    re_path(
        r"^mapping/sessions/(?P<pk>\d+)/(?P<action>finish|resume|discard)$",
        mapping.SessionAction.as_view(),
        name="mapping-action",
    ),
    path(
        "mapping/sessions/<int:pk>/publish",
        mapping.SessionPublish.as_view(),
        name="mapping-publish",
    ),
    path("tags/", TagList.as_view(), name="tag-list"),
    path("tags/<int:pk>/", TagDetail.as_view(), name="tag-detail"),
    re_path(
        r"^tags/(?P<pk>\d+)/print\.(?P<extension>png|pdf)$",
        TagPrint.as_view(),
        name="tag-print",
    ),
]
