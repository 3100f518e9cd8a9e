"""Robot administration in the app: register (token shown once), assign buildings, rotate,
revoke; styled 403 and 404 pages; at desktop and phone sizes in a real browser."""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, BrowserContext, expect

from tests.browser_support import Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


@pytest.fixture(params=[{"width": 1440, "height": 900}, {"width": 390, "height": 844}],
                ids=["desktop", "phone"])  # fmt: skip
def sized(browser: Browser, request: pytest.FixtureRequest) -> Iterator[BrowserContext]:
    opened = browser.new_context(viewport=request.param)
    opened.set_default_timeout(15_000)
    yield opened
    opened.close()


def test_an_admin_registers_rotates_and_revokes_a_robot(sized: BrowserContext, demo: Demo) -> None:
    page = open_as(sized, demo, "admin", "/robots/")
    page.fill("#register-name", "tb3_7")
    page.fill("#register-description", "the new one")
    page.click("#register-submit")
    token = page.locator("#token-value")
    expect(token).to_have_text(re.compile(r"\S{20,}"))
    first = token.inner_text()
    row = page.locator("tr[data-robot=tb3_7]")
    expect(row.locator("input[data-building=boccioni_1]")).to_be_checked()
    screenshot(page, f"robots-admin-{page.viewport_size['width']}")  # type: ignore[index]

    row.locator("button[data-action=rotate]").click()
    expect(page.locator("#token-title")).to_contain_text("New token of tb3_7")
    expect(token).not_to_have_text(first)

    row.locator("input[data-building=boccioni_1]").click()  # its only building
    expect(page.locator("#register-error")).to_contain_text("revoke it")
    page.reload()  # the token is not shown again; the robot keeps its building
    expect(page.locator("#token-box")).to_be_hidden()
    expect(row.locator("input[data-building=boccioni_1]")).to_be_checked()

    row.locator("button[data-action=revoke]").click()
    page.locator("#revoke-dialog button[value=confirm]").click()
    expect(row).to_have_count(0)


def test_operators_get_a_styled_403_and_everyone_a_styled_404(
    context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "operator", "/robots/")
    expect(page.locator(".error-page[data-status='403']")).to_be_visible()
    expect(page.locator("#nav-robots")).to_have_count(0)
    page.goto(demo.url("/buildings/nowhere/"))
    expect(page.locator(".error-page[data-status='404']")).to_contain_text("Not found")
    screenshot(page, "not-found")
