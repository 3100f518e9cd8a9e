"""Page views of the web UI: thin adapters that render a template with the user's role.

Pages carry no data of their own beyond names and roles: the browser reads the REST API
and speaks rosbridge. What a page shows depends on the role the user holds where the
page's subject lives (``maps.access``); a building or robot the user may not see is a
404, as in the API.
"""

from __future__ import annotations

from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import render

from maps.access import Role, buildings_for, buildings_where, global_role, role_in
from maps.models import Building, SubMap
from maps.page_context import page_context, role_name
from robots.models import Robot


def _building(request: HttpRequest, code: str) -> tuple[Building, Role]:
    """Return building ``code`` and the user's role there; 404 if they may not see it."""
    building = Building.objects.filter(code=code).first()
    role = role_in(request.user, building) if building is not None else Role.NONE
    if building is None or role is Role.NONE:
        raise Http404("No such building.")
    return building, role


ERRORS = {
    403: ("Not allowed", "Your role does not let you do this here. Ask an admin of the building."),
    404: ("Not found", "There is nothing here, or nothing you may see."),
}


def error_page(request: HttpRequest, status: int) -> HttpResponse:
    """A 403 or 404 in the app's own style, with the navigation of whoever asked."""
    title, text = ERRORS[status]
    extra = {"status": status, "title": title, "text": text}
    if request.user.is_authenticated:
        context = page_context(request, global_role(request.user), page="", **extra)
    else:
        context = {"role": "none", **extra}
    return render(request, "error.html", context, status=status)


def not_found(request: HttpRequest, exception: Exception | None = None) -> HttpResponse:  # noqa: ARG001 (Django's handler)
    return error_page(request, 404)


def forbidden(request: HttpRequest, exception: Exception | None = None) -> HttpResponse:  # noqa: ARG001 (Django's handler)
    return error_page(request, 403)


@login_required
def fleet(request: HttpRequest) -> HttpResponse:
    role = global_role(request.user)
    return render(request, "pages/fleet.html", page_context(request, role, page="fleet"))


@login_required
def robot(request: HttpRequest, name: str) -> HttpResponse:
    """A robot's page; the role is the strongest the user holds in the robot's buildings."""
    found = Robot.objects.filter(name=name).first()
    buildings = list(found.buildings.order_by("code")) if found is not None else []
    role = max((role_in(request.user, b) for b in buildings), default=Role.NONE)
    if found is None or role is Role.NONE:
        raise Http404("No such robot.")
    visible = [b for b in buildings if role_in(request.user, b) > Role.NONE]
    config = {"robot": found.name, "buildings": [b.code for b in visible]}
    context = page_context(request, role, page="fleet", robot=found, config=config)
    return render(request, "pages/robot.html", context)


@login_required
def robots(request: HttpRequest) -> HttpResponse:
    """Robot administration, for admins."""
    role = global_role(request.user)
    if role < Role.ADMIN:
        raise PermissionDenied("Only admins administer robots.")
    administered = buildings_where(request.user, Role.ADMIN).order_by("code")
    codes = list(administered.values_list("code", flat=True))
    context = page_context(request, role, page="robots", config={"buildings": codes})
    return render(request, "pages/robots.html", context)


@login_required
def buildings(request: HttpRequest) -> HttpResponse:
    role = global_role(request.user)
    rows = [
        (b, role_name(role_in(request.user, b)), b.submaps.count(), b.tags.count())
        for b in buildings_for(request.user).order_by("code")
    ]
    context = page_context(request, role, page="buildings", rows=rows)
    return render(request, "pages/buildings.html", context)


@login_required
def building(request: HttpRequest, code: str) -> HttpResponse:
    found, role = _building(request, code)
    submaps = found.submaps.defer("image").order_by("code")
    tags = found.tags.select_related("submap", "links_to").order_by("marker_id")
    config = {"building": found.code}
    context = page_context(
        request, role, page="buildings", building=found, submaps=submaps, tags=tags, config=config
    )
    return render(request, "pages/building.html", context)


@login_required
def building_map(request: HttpRequest, code: str) -> HttpResponse:
    """Every sub-map of a building as one floor plan, with every robot live on it."""
    found, role = _building(request, code)
    config = {"building": found.code}
    context = page_context(request, role, page="building-map", building=found, config=config)
    return render(request, "pages/building_map.html", context)


@login_required
def submap(request: HttpRequest, code: str, map: str) -> HttpResponse:
    found, role = _building(request, code)
    sub: SubMap | None = found.submaps.defer("image").filter(code=map).first()
    if sub is None:
        raise Http404("No such sub-map.")
    others = list(found.submaps.defer("image").order_by("code").values_list("code", flat=True))
    config = {"building": found.code, "map": sub.code, "submaps": others}
    context = page_context(
        request, role, page="buildings", building=found, submap=sub, config=config
    )
    return render(request, "pages/submap.html", context)


@login_required
def upload(request: HttpRequest, code: str) -> HttpResponse:
    found, role = _building(request, code)
    if role < Role.ADMIN:
        raise PermissionDenied("Only admins upload sub-maps.")
    config = {"building": found.code}
    context = page_context(request, role, page="buildings", building=found, config=config)
    return render(request, "pages/upload.html", context)
