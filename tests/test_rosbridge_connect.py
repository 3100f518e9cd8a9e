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


@pytest.mark.parametrize(
    "origin",
    [
        "http://testserver:8001",  # another port of our host
        "https://testserver",  # another scheme
        "http://testserver.evil.example",
        "null",
        "http://[::1",
    ],
)
async def test_it_rejects_a_session_from_another_scheme_host_or_port(rosbridge, operator, origin):
    with pytest.raises(Refused):
        await rosbridge(user=operator, origin=origin)


@pytest.mark.parametrize(
    ("host", "origin"),
    [
        ("127.0.0.1:8000", "http://127.0.0.1:8000"),
        ("[::1]:8000", "http://[::1]:8000"),
        ("localhost", "http://localhost:80"),
    ],
)
async def test_it_admits_a_session_from_the_very_origin_it_was_reached_at(
    rosbridge, operator, host, origin
):
    await rosbridge(user=operator, origin=origin, host=host)


async def test_it_admits_a_session_from_a_trusted_origin(rosbridge, operator, settings):
    settings.CSRF_TRUSTED_ORIGINS = ["https://cloudnav.example.org"]
    await rosbridge(user=operator, origin="https://cloudnav.example.org", host="127.0.0.1:8000")


async def test_it_rejects_a_session_reaching_a_host_that_is_not_allowed(rosbridge, operator):
    with pytest.raises(Refused):
        await rosbridge(user=operator, origin="http://evil.example", host="evil.example")
