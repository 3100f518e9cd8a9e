"""Personas and builders shared by the tests.

Personas: ``admin``, ``operator`` and ``viewer`` are members of their group and of the
building they are given; ``outsider`` is a signed-in user with no group and no building.
Builders take keyword arguments and fill the rest with ``kwargs.setdefault``.
"""

from __future__ import annotations

from typing import Any

import pytest
from django.contrib.auth.models import Group, User

from maps.models import Building
from robots.models import Robot
from robots.services import register_robot

pytest_plugins = ["tests.fixtures_live"]


def make_user(username: str, group: str | None = None, **kwargs: Any) -> User:
    kwargs.setdefault("password", "pw-" + username)
    user = User.objects.create_user(username=username, **kwargs)
    if group:
        user.groups.add(Group.objects.get_or_create(name=group)[0])
    return user


def make_building(**kwargs: Any) -> Building:
    kwargs.setdefault("code", "boccioni_1")
    kwargs.setdefault("name", "Boccioni building")
    kwargs.setdefault("zip_code", "56037")
    members = kwargs.pop("members", ())
    building = Building.objects.create(**kwargs)
    building.members.add(*members)
    return building


def make_robot(**kwargs: Any) -> tuple[Robot, str]:
    """Register a robot and return it with its token."""
    kwargs.setdefault("name", "r1")
    return register_robot(**kwargs)


@pytest.fixture
def admin(db: None) -> User:
    return make_user("admin", "admin")


@pytest.fixture
def operator(db: None) -> User:
    return make_user("operator", "operator")


@pytest.fixture
def viewer(db: None) -> User:
    return make_user("viewer", "viewer")


@pytest.fixture
def outsider(db: None) -> User:
    return make_user("outsider")


@pytest.fixture
def building(admin: User, operator: User, viewer: User) -> Building:
    return make_building(members=[admin, operator, viewer])
