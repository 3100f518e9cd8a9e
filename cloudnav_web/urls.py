"""Top-level URLs: REST API, OpenAPI schema and docs, admin, and the apps' pages."""

from __future__ import annotations

from django.contrib import admin
from django.urls import include, path
from drf_spectacular.views import SpectacularAPIView, SpectacularSwaggerView

urlpatterns = [
    path("admin/", admin.site.urls),
    path("api/schema/", SpectacularAPIView.as_view(), name="schema"),
    path("api/docs/", SpectacularSwaggerView.as_view(url_name="schema"), name="api-docs"),
    path("api/", include("maps.urls")),
    path("api/", include("robots.urls")),
    path("", include("telemetry.urls")),
]
