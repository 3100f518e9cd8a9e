"""The context every page of the web UI shares: the user's role where the page's subject
lives, what it lets them do, and the buildings they may see (``maps.access``)."""

from __future__ import annotations

from typing import Any

from django.http import HttpRequest

from maps.access import Role, buildings_for, global_role


def role_name(role: Role) -> str:
    """The role as pages and their scripts name it: ``admin``, ``operator``, ..."""
    return role.name.lower()


def page_context(request: HttpRequest, role: Role, **kwargs: Any) -> dict[str, Any]:
    """Template context every page shares; ``config`` is handed to the page's script."""
    buildings = list(buildings_for(request.user).order_by("code"))
    config = {
        "role": role_name(role),
        "user": request.user.get_username(),
        "connect": global_role(request.user) > Role.NONE,
        **kwargs.pop("config", {}),
    }
    return {
        "role": role_name(role),
        "may_drive": role >= Role.OPERATOR,
        "may_edit": role >= Role.ADMIN,
        "nav_buildings": buildings,
        "config": config,
        **kwargs,
    }
