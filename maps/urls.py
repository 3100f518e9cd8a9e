"""Map store routes under /api/."""

from __future__ import annotations

from django.urls import path, re_path

from . import views
from .mapping import views as mapping

building = "buildings/<slug:building>"
submap = f"{building}/maps/<slug:map>"
version = f"{submap}/versions/<int:number>"

urlpatterns = [
    path("buildings/", views.BuildingList.as_view(), name="building-list"),
    path(f"{building}/", views.BuildingDetail.as_view(), name="building-detail"),
    path(f"{building}/members/", views.MemberList.as_view(), name="member-list"),
    path(f"{building}/members/<str:username>/", views.MemberDetail.as_view(), name="member-detail"),
    path(f"{building}/maps/", views.SubMapList.as_view(), name="submap-list"),
    path(f"{submap}/", views.SubMapDetail.as_view(), name="submap-detail"),
    path(f"{submap}/image", views.SubMapImage.as_view(), name="submap-image"),
    path(f"{submap}/grid", views.SubMapGrid.as_view(), name="submap-grid"),
    path(f"{submap}/export", views.SubMapExport.as_view(), name="submap-export"),
    path(f"{submap}/bundle", views.SubMapBundle.as_view(), name="submap-bundle"),
    path(f"{submap}/versions/", views.VersionList.as_view(), name="version-list"),
    path(f"{submap}/versions/compare", views.VersionComparison.as_view(), name="version-compare"),
    path(f"{version}/", views.VersionDetail.as_view(), name="version-detail"),
    path(f"{version}/image", views.VersionImage.as_view(), name="version-image"),
    path(f"{version}/grid", views.VersionGrid.as_view(), name="version-grid"),
    path(f"{version}/rollback", views.VersionRollback.as_view(), name="version-rollback"),
    path(f"{submap}/changes/", mapping.ProposalList.as_view(), name="change-list"),
    path(f"{submap}/changes/<int:pk>/", mapping.ProposalDetail.as_view(), name="change-detail"),
    re_path(
        r"^buildings/(?P<building>[-\w]+)/maps/(?P<map>[-\w]+)/changes/(?P<pk>\d+)/"
        r"(?P<decision>accept|reject)$",
        mapping.ProposalDecision.as_view(),
        name="change-decision",
    ),
    path(f"{submap}/keyframes", views.SubMapKeyframes.as_view(), name="submap-keyframes"),
    path("relocalise", views.Relocalise.as_view(), name="relocalise"),
    path(f"{building}/topology", views.Topology.as_view(), name="topology"),
    path(
        f"{building}/topology/validation",
        views.TopologyValidation.as_view(),
        name="topology-validation",
    ),
    path(f"{building}/route", views.Route.as_view(), name="route"),
    path(f"{building}/tags/print.pdf", views.BuildingTagSheet.as_view(), name="tag-sheet"),
    path("mapping/sessions/", mapping.SessionList.as_view(), name="mapping-list"),
    path("mapping/sessions/<int:pk>/", mapping.SessionDetail.as_view(), name="mapping-detail"),
    path("mapping/sessions/<int:pk>/grid", mapping.SessionGrid.as_view(), name="mapping-grid"),
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
    path("tags/", views.TagList.as_view(), name="tag-list"),
    path("tags/<int:pk>/", views.TagDetail.as_view(), name="tag-detail"),
    re_path(
        r"^tags/(?P<pk>\d+)/print\.(?P<extension>png|pdf)$",
        views.TagPrint.as_view(),
        name="tag-print",
    ),
]
