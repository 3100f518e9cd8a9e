"""Administration in the app: robots (register with the token shown once, assign buildings,
rotate, revoke), buildings (create) and their members and roles; styled 403 and 404 pages; at
desktop and phone sizes in a real browser."""

from __future__ import annotations

import re

import pytest
from django.contrib.auth.models import User
from playwright.sync_api import BrowserContext, expect

from maps.models import Building, Membership
from robots.services import register_robot
from tests.browser_support import BUILDING, ROBOT, Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


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

    # Rotating cuts a connected robot off: asked first; cancelled, the token stands.
    row.locator("button[data-action=rotate]").click()
    expect(page.locator("#rotate-dialog")).to_contain_text("stops working")
    page.locator("#rotate-dialog button[value=cancel]").click()
    expect(token).to_have_text(first)
    row.locator("button[data-action=rotate]").click()
    page.locator("#rotate-dialog button[value=confirm]").click()
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


def test_an_admin_creates_a_building_and_becomes_its_member(
    sized: BrowserContext, demo: Demo
) -> None:
    page = open_as(sized, demo, "admin", "/buildings/")
    page.click("#new-building")
    form = page.locator("#building-form")
    form.locator("input[name=code]").fill("boccioni_1")  # taken
    form.locator("input[name=name]").fill("Boccioni, floor 2")
    form.locator("input[name=zip_code]").fill("56037")
    form.locator("input[name=address]").fill("Via Boccioni 1")
    page.click("#building-create")
    expect(page.locator("#building-error")).to_contain_text("code")
    form.locator("input[name=code]").fill("boccioni_2")
    screenshot(page, f"building-create-{page.viewport_size['width']}")  # type: ignore[index]
    page.click("#building-create")
    expect(page).to_have_url(demo.url("/buildings/boccioni_2/"))
    expect(page.locator("h1")).to_have_text("Boccioni, floor 2")
    page.goto(demo.url("/buildings/"))
    expect(page.locator(".building-card")).to_have_count(2)


def test_only_admins_may_create_buildings(context: BrowserContext, demo: Demo) -> None:
    page = open_as(context, demo, "operator", "/buildings/")
    expect(page.locator(".building-card")).to_have_count(1)
    expect(page.locator("#new-building")).to_have_count(0)
    # Asked by hand from the page, with its session and CSRF token, the server refuses.
    status = page.evaluate(
        """async () => {
            const token = document.cookie.match(/csrftoken=([^;]+)/)[1];
            const answer = await fetch("/api/buildings/", {
                method: "POST",
                headers: { "Content-Type": "application/json", "X-CSRFToken": token },
                body: JSON.stringify({ code: "sneaky", name: "Sneaky" }),
            });
            return answer.status;
        }"""
    )
    assert status == 403


def test_an_admin_adds_and_removes_a_member_of_a_building(
    sized: BrowserContext, demo: Demo
) -> None:
    page = open_as(sized, demo, "admin", f"/buildings/{BUILDING}/")
    rows = page.locator("#member-rows tr")
    expect(rows).to_have_count(3)  # the demo's admin, operator and viewer
    page.fill("#member-name", "nobody")
    page.click("#member-add")
    expect(page.locator("#member-error")).to_contain_text("nobody")
    page.locator("tr[data-member=viewer] button[data-action=remove]").click()
    expect(rows).to_have_count(2)
    screenshot(page, f"building-members-{page.viewport_size['width']}")  # type: ignore[index]

    viewer = open_as(page.context.browser.new_context(), demo, "viewer", f"/buildings/{BUILDING}/")  # type: ignore[union-attr]
    expect(viewer.locator(".error-page[data-status='404']")).to_be_visible()
    viewer.context.close()

    page.fill("#member-name", "viewer")
    page.click("#member-add")
    expect(page.locator("tr[data-member=viewer]")).to_be_visible()
    expect(page.locator("#member-name")).to_have_value("")
    page.reload()
    expect(rows).to_have_count(3)


@pytest.fixture
def annex(demo: Demo) -> Building:
    """A second building, annex_1, with robot_9; the demo's admin and operator are members
    in the role of their group (made before Chromium starts: the database is then sync)."""
    annex = Building.objects.create(code="annex_1", name="Annex")
    for name in ("admin", "operator"):
        Membership.objects.create(building=annex, user=User.objects.get(username=name))
    register_robot("robot_9", [annex], "in the annex")
    return annex


def test_an_operator_of_one_building_only_views_another_after_an_admin_changes_the_role(
    annex: Building, sized: BrowserContext, demo: Demo
) -> None:
    page = open_as(sized, demo, "admin", "/buildings/annex_1/")
    operator = page.locator("tr[data-member=operator]")
    expect(operator.locator("select[data-action=role]")).to_have_value("operator")  # the group's
    operator.locator("select[data-action=role]").select_option("viewer")
    expect(operator).to_have_attribute("data-role", "viewer")
    page.locator("tr[data-member=admin] select[data-action=role]").select_option("viewer")
    expect(page.locator("#member-error")).to_contain_text("no admin left")
    expect(page.locator("tr[data-member=admin]")).to_have_attribute("data-role", "admin")
    screenshot(page, f"building-roles-{page.viewport_size['width']}")  # type: ignore[index]
    page.reload()
    expect(operator.locator("select[data-action=role]")).to_have_value("viewer")

    # The operator drives robot_0 in the demo building and only watches robot_9 here.
    size = page.viewport_size
    second = page.context.browser.new_context(viewport=size)  # type: ignore[union-attr]
    mine = open_as(second, demo, "operator", f"/robots/{ROBOT}/")
    expect(mine.locator("#conn-state")).to_contain_text("Live")
    mine.click("#lock-acquire")
    expect(mine.locator("#lock-state")).to_have_text("You are driving")
    mine.goto(demo.url("/robots/robot_9/"))
    expect(mine.locator("#conn-state")).to_contain_text("Live")
    expect(mine.locator("h1")).to_contain_text("robot_9")
    expect(mine.locator("#teleop-card")).to_have_count(0)
    expect(mine.locator("#lock-acquire")).to_have_count(0)
    screenshot(mine, f"robot-viewed-not-driven-{page.viewport_size['width']}")  # type: ignore[index]
    mine.goto(demo.url("/buildings/"))
    expect(mine.locator(".building-card", has_text="Annex")).to_contain_text("viewer")
    mine.context.close()
