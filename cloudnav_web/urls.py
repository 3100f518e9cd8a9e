"""Top-level URLs: REST API, OpenAPI schema and docs, admin, and the apps' pages."""

from __future__ import annotations

from django.contrib import admin
from django.contrib.auth import views as auth_views
from django.urls import include, path
from drf_spectacular.views import SpectacularAPIView, SpectacularSwaggerView

from . import pages

handler403 = pages.forbidden
handler404 = pages.not_found

urlpatterns = [
    path("admin/", admin.site.urls),
    path("api/schema/", SpectacularAPIView.as_view(), name="schema"),
    path("api/docs/", SpectacularSwaggerView.as_view(url_name="schema"), name="api-docs"),
    path("api/", include("maps.urls")),
    path("api/", include("robots.urls")),
    path("", include("telemetry.urls")),
    path("accounts/login/", auth_views.LoginView.as_view(), name="login"),
    path("accounts/logout/", auth_views.LogoutView.as_view(), name="logout"),
    path("", pages.fleet, name="fleet-page"),
    path("robots/", pages.robots, name="robots-page"),
    path("robots/<slug:name>/", pages.robot, name="robot-page"),
    path("buildings/", pages.buildings, name="buildings-page"),
    path("buildings/<slug:code>/", pages.building, name="building-page"),
    path("buildings/<slug:code>/map/", pages.building_map, name="building-map-page"),
    path("buildings/<slug:code>/upload/", pages.upload, name="upload-page"),
    path("buildings/<slug:code>/maps/<slug:map>/", pages.submap, name="submap-page"),
]
