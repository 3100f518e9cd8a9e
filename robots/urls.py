"""Robot registry routes under /api/."""

from __future__ import annotations

from django.urls import path

from . import fleet_views, mission_views, views

urlpatterns = [
    path("robots/", views.RobotList.as_view(), name="robot-list"),
    path("robots/<slug:name>/", views.RobotDetail.as_view(), name="robot-detail"),
    path("robots/<slug:name>/rotate_token", views.RotateToken.as_view(), name="robot-rotate"),
    path("fleet/", fleet_views.FleetList.as_view(), name="fleet"),
    path("missions/", mission_views.MissionList.as_view(), name="missions"),
    path(
        "missions/<int:pk>/<slug:command>",
        mission_views.MissionCommand.as_view(),
        name="mission-command",
    ),
]
