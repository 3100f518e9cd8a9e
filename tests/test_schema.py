"""The OpenAPI 3 schema and its browsable docs."""

from __future__ import annotations

from django.contrib.auth.models import User

from tests.conftest import client_for


def test_the_schema_is_openapi_3_and_lists_the_map_store(admin: User) -> None:
    response = client_for(admin).get("/api/schema/", HTTP_ACCEPT="application/vnd.oai.openapi+json")
    schema = response.json()
    assert schema["openapi"].startswith("3.")
    for path in [
        "/api/buildings/",
        "/api/buildings/{building}/maps/{map}/bundle",
        "/api/buildings/{building}/route",
        "/api/tags/{id}/print.{extension}",
        "/api/robots/",
    ]:
        assert path in schema["paths"] or path.replace("{id}", "{pk}") in schema["paths"], path


def test_the_docs_page_loads_its_assets_locally(admin: User) -> None:
    page = client_for(admin).get("/api/docs/").content.decode()
    assert "swagger" in page.lower()
    assert "cdn" not in page.lower()


def test_the_docs_assets_are_served_by_the_app(admin: User) -> None:
    page = client_for(admin).get("/api/docs/").content.decode()
    asset = next(part.split('"')[0] for part in page.split('src="')[1:] if "swagger" in part)
    response = client_for(admin).get(asset)
    assert response.status_code == 200
