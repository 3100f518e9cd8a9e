"""The embedded database (SQLite) holds ordinary concurrency (issue 23 point 15): admins
making versions at once each get their answer, none a 500 "database is locked" (live
daphne on the test's SQLite file, real HTTP)."""

from __future__ import annotations

import asyncio

import httpx
import pytest
from django.db import connection

from maps.models import SubMapVersion
from tests.conftest import make_building, make_submap, make_user
from tests.fixtures_live import session_cookie

pytestmark = pytest.mark.django_db(transaction=True)

ADMINS = 6
EDITS = 10
CSRF = "c" * 32  # a session's unsafe request carries Django's CSRF cookie and the same token
URL = "/api/buildings/boccioni_1/maps/CorridorA/"


@pytest.fixture
def admin_cookies() -> list[str]:
    """Six admins of the building holding CorridorA: their sessions' cookies."""
    assert connection.vendor == "sqlite"
    admins = [make_user(f"admin{i}", "admin") for i in range(ADMINS)]
    make_submap(make_building(members=admins))
    return [f"{session_cookie(a).decode()}; csrftoken={CSRF}" for a in admins]


async def edits_by(http: httpx.AsyncClient, cookie: str, who: int) -> list[int]:
    """One admin's edits of the sub-map's origin, one after another: each a new version."""
    headers = {"Cookie": cookie, "X-CSRFToken": CSRF}
    answers = []
    for i in range(EDITS):
        origin = [float(who) + 1.0, float(i), 0.0]  # never the first version's 0, 0, 0
        answer = await http.patch(URL, json={"origin": origin}, headers=headers)
        answers.append(answer.status_code)
    return answers


async def test_six_admins_making_versions_at_once_all_succeed(daphne_server, admin_cookies):
    async with httpx.AsyncClient(base_url=daphne_server.url, timeout=60) as http:
        answers = await asyncio.gather(
            *(edits_by(http, cookie, who) for who, cookie in enumerate(admin_cookies))
        )
    assert [code for codes in answers for code in codes] == [200] * ADMINS * EDITS, (
        daphne_server.log()[-3000:]
    )
    numbers = await asyncio.to_thread(
        lambda: sorted(SubMapVersion.objects.values_list("number", flat=True))
    )
    assert numbers == list(range(1, ADMINS * EDITS + 2))


async def test_two_admins_accepting_one_proposal_at_once_make_one_version(
    daphne_server, admin_cookies
):
    from maps.models import ChangeProposal, SubMap

    def propose() -> int:
        submap = SubMap.objects.get(code="CorridorA")
        cells = [[5, 5], [5, 6], [6, 5]]
        made = ChangeProposal.objects.create(
            submap=submap, based_on=1, added=cells, added_passes=[2] * 3, passes=2, scans=50
        )
        return made.pk

    pk = await asyncio.to_thread(propose)
    accept = f"{URL}changes/{pk}/accept"
    async with httpx.AsyncClient(base_url=daphne_server.url, timeout=60) as http:
        answers = await asyncio.gather(
            *(
                http.post(accept, json={}, headers={"Cookie": cookie, "X-CSRFToken": CSRF})
                for cookie in admin_cookies[:2]
            )
        )
    codes = sorted(a.status_code for a in answers)
    assert codes[0] == 200, daphne_server.log()[-3000:]
    assert codes[1] in (400, 409), [a.text for a in answers]
    count = await asyncio.to_thread(SubMapVersion.objects.count)
    assert count == 2
