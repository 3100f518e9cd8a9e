"""Who may open a rosbridge connection, and on which paths."""

from __future__ import annotations

import pytest

from tests.fixtures_live import Refused

pytestmark = pytest.mark.django_db(transaction=True)


async def test_it_admits_a_robot_by_query_token(rosbridge, token):
    client = await rosbridge(token=token)
    assert (await client.call("/rosapi/get_time"))["result"] is True


async def test_it_admits_a_robot_by_authorization_header(rosbridge, token):
    client = await rosbridge(header_token=token)
    assert (await client.call("/rosapi/get_time"))["result"] is True


@pytest.mark.parametrize("path", ["/", "/rosbridge", "/rosbridge/"])
async def test_it_serves_rosbridge_at_root_and_rosbridge(rosbridge, token, path):
    client = await rosbridge(token=token, path=path)
    assert (await client.call("rosapi/get_time"))["result"] is True


async def test_it_rejects_an_unregistered_robot(rosbridge):
    with pytest.raises(Refused):
        await rosbridge(token="cnr_not-a-token")


async def test_it_rejects_anonymous(rosbridge):
    with pytest.raises(Refused):
        await rosbridge()


async def test_it_rejects_outsider(rosbridge, outsider):
    with pytest.raises(Refused):
        await rosbridge(user=outsider)


@pytest.mark.parametrize("persona", ["admin", "operator", "viewer"])
async def test_it_admits_people_with_a_role(rosbridge, building, persona, request):
    client = await rosbridge(user=request.getfixturevalue(persona))
    assert (await client.call("/rosapi/get_time"))["result"] is True


async def test_it_rejects_a_session_from_a_foreign_origin(rosbridge, operator):
    with pytest.raises(Refused):
        await rosbridge(user=operator, origin="http://evil.example")


async def test_it_rejects_a_session_without_origin(rosbridge, operator):
    with pytest.raises(Refused):
        await rosbridge(user=operator, origin=None)


async def test_a_bad_token_wins_over_a_good_session(rosbridge, operator):
    with pytest.raises(Refused):
        await rosbridge(user=operator, token="cnr_wrong")
