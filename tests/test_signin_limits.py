"""Sign-ins are rate-limited: the login page, the admin and HTTP Basic on the API share one
count per name and address, kept in the database (django-axes)."""

from __future__ import annotations

import base64

import pytest
from django.conf import settings
from django.test import Client
from rest_framework.test import APIClient

from cloudnav_web.bodies import _credentials_hold
from tests.conftest import make_user

LIMIT = 3


@pytest.fixture(autouse=True)
def limits(settings):
    settings.AXES_ENABLED = True
    settings.AXES_FAILURE_LIMIT = LIMIT


@pytest.fixture
def user(db):
    return make_user("alice", "viewer", password="right-password")


def basic(username: str, password: str) -> str:
    return "Basic " + base64.b64encode(f"{username}:{password}".encode()).decode()


def sign_in(password: str) -> int:
    response = Client().post(
        "/accounts/login/", {"username": "alice", "password": password}, REMOTE_ADDR="10.0.0.1"
    )
    return int(response.status_code)


def test_the_login_page_refuses_after_too_many_failures_even_the_right_password(user):
    assert sign_in("right-password") == 302
    for _ in range(LIMIT - 1):
        assert sign_in("wrong") == 200  # the form again, with its error
    assert sign_in("wrong") == 429
    assert sign_in("right-password") == 429


def test_a_locked_out_sign_in_gets_a_page_that_says_so_and_for_how_long(user):
    for _ in range(LIMIT):
        sign_in("wrong")
    response = Client().post(
        "/accounts/login/", {"username": "alice", "password": "x"}, REMOTE_ADDR="10.0.0.1"
    )
    assert response.status_code == 429
    page = response.content.decode()
    assert "Too many failed sign-ins" in page
    assert 'class="card login-card" id="locked-out"' in page
    assert "<strong>alice</strong>" in page
    assert f"for {settings.AXES_COOLOFF_TIME.total_seconds() // 60:.0f} minutes" in page
    assert 'href="/accounts/login/"' in page


def test_another_address_is_not_locked_out(user):
    for _ in range(LIMIT):
        sign_in("wrong")
    response = Client().post(
        "/accounts/login/",
        {"username": "alice", "password": "right-password"},
        REMOTE_ADDR="10.0.0.2",
    )
    assert response.status_code == 302


def test_http_basic_refuses_after_too_many_failures_even_the_right_password(user):
    client = APIClient(REMOTE_ADDR="10.0.0.1")
    assert (
        client.get(
            "/api/buildings/", HTTP_AUTHORIZATION=basic("alice", "right-password")
        ).status_code
        == 200
    )
    for _ in range(LIMIT - 1):
        response = client.get("/api/buildings/", HTTP_AUTHORIZATION=basic("alice", "wrong"))
        assert response.status_code == 401
    response = client.get("/api/buildings/", HTTP_AUTHORIZATION=basic("alice", "wrong"))
    assert response.status_code == 429
    response = client.get("/api/buildings/", HTTP_AUTHORIZATION=basic("alice", "right-password"))
    assert response.status_code == 429, response.content


def test_the_early_look_at_basic_credentials_counts_and_respects_the_limit(user):
    right = {b"authorization": basic("alice", "right-password").encode()}
    wrong = {b"authorization": basic("alice", "wrong").encode()}
    assert _credentials_hold(right, "10.0.0.1")
    for _ in range(LIMIT):
        assert not _credentials_hold(wrong, "10.0.0.1")
    assert not _credentials_hold(right, "10.0.0.1")
    assert _credentials_hold(right, "10.0.0.9")
