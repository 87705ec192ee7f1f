"""The admin dashboard's plots render in Chromium with the data of a 20-participant study (the screenshot is in
test-artifacts/admin-dashboard.png), and its numbers read as tables without them."""

from __future__ import annotations

import pytest
from demostudy import make_app

from simulation.run import simulate

from .pagehelp import new_context, require_browser, screenshot, until

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def collected(tmp_path_factory, demo_resources):
    """gunicorn with an admin password serving the demo study that 20 simulated participants completed."""
    from serverproc import StudyServer
    from werkzeug.security import generate_password_hash

    require_browser()
    tmp = tmp_path_factory.mktemp("dashboard")
    url = f"sqlite:///{tmp / 'study.sqlite3'}"
    assert simulate(20, seed=7, study="demo", app=make_app(tmp, url))["completed"] == 20
    server = StudyServer(tmp / "instance", url, migrate=False)
    server.env["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash("dashboard-password")
    with server:
        yield server.base


def test_the_plots_render_with_a_studys_data(collected, browser):
    context = new_context(browser, test_hook=False, viewport={"width": 1400, "height": 1800})
    page = context.new_page()
    page.goto(f"{collected}/admin/login")
    page.fill("input[name=password]", "dashboard-password")
    page.click("button[type=submit]")
    until(page, "location.pathname === '/admin/'")
    until(page, "[...document.querySelectorAll('.plots img')].every((i) => i.complete)")
    sizes = page.evaluate("() => [...document.querySelectorAll('.plots img')].map((i) => [i.naturalWidth, "
                          "i.naturalHeight, i.getBoundingClientRect().width])")
    assert len(sizes) == 4 and all(w > 300 and h > 100 and shown > 300 for w, h, shown in sizes), sizes
    page.click("#glance-trial-times >> xpath=ancestor::details/summary")
    rows = page.locator("#glance-trial-times tbody tr")
    assert rows.count() >= 9 and "none" in rows.first.inner_text()
    screenshot(page, "admin-dashboard")
    context.close()
