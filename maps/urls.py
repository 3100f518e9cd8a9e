"""Map store routes under /api/."""

from __future__ import annotations

from django.urls import path, re_path

from . import views

building = "buildings/<slug:building>"
submap = f"{building}/maps/<slug:map>"

urlpatterns = [
    path("buildings/", views.BuildingList.as_view(), name="building-list"),
    path(f"{building}/", views.BuildingDetail.as_view(), name="building-detail"),
    path(f"{building}/maps/", views.SubMapList.as_view(), name="submap-list"),
    path(f"{submap}/", views.SubMapDetail.as_view(), name="submap-detail"),
    path(f"{submap}/image", views.SubMapImage.as_view(), name="submap-image"),
    path(f"{submap}/grid", views.SubMapGrid.as_view(), name="submap-grid"),
    path(f"{submap}/export", views.SubMapExport.as_view(), name="submap-export"),
    path(f"{submap}/bundle", views.SubMapBundle.as_view(), name="submap-bundle"),
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
    path("tags/", views.TagList.as_view(), name="tag-list"),
    path("tags/<int:pk>/", views.TagDetail.as_view(), name="tag-detail"),
    re_path(
        r"^tags/(?P<pk>\d+)/print\.(?P<extension>png|pdf)$",
        views.TagPrint.as_view(),
        name="tag-print",
    ),
]
