"""The admin dashboard draws what an experimenter checks during collection (participants over time by outcome,
progress per row and condition, trial time per condition and scene, flags over time) as server-drawn SVG images,
each with a table of the same numbers for readers without images."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest
from demostudy import make_app
from flowhelp import csrf
from werkzeug.security import generate_password_hash

from simulation.run import simulate
from study_server.base.extensions import db
from study_server.base.models import Participant
from study_server.experimenter import plots

PASSWORD = "plots password"
SVG = "{http://www.w3.org/2000/svg}"


def completed_study(tmp_path):
    """An app whose demo study 6 simulated participants completed; one flagged, one excluded."""
    app = make_app(tmp_path, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    assert simulate(6, seed=3, study="demo", app=app)["completed"] == 6
    with app.app_context():
        people = db.session.query(Participant).order_by(Participant.id).all()
        people[0].flags = [{"reason": "a test", "at": "2026-12-01T10:00:00", "times": 1}]
        people[1].flags = [{"reason": "seen", "at": "2026-12-01T11:00:00", "times": 1,
                            "cleared_at": "2026-12-01T12:00:00"}]
        people[2].status = "excluded"
        db.session.commit()
    return app


@pytest.fixture(scope="module")
def studied(tmp_path_factory, demo_resources):
    """:func:`completed_study`, shared by the tests that only read it."""
    return completed_study(tmp_path_factory.mktemp("studied"))


def admin(app):
    c = app.test_client()
    c.post("/admin/login", data={"csrf_token": csrf(c.get("/admin/login")), "password": PASSWORD})
    return c


def test_the_numbers_are_the_studys(studied):
    with studied.app_context():
        study = studied.extensions["studies"]["demo"].study
        glance = plots.glance(study)
    (day, outcomes), = glance["arrivals"]  # all arrived today
    assert outcomes == {"completed": 5, "excluded": 1}
    assert sum(t["n"] for t in glance["trial_times"]) == 6 * 9  # every counted trial done
    assert {t["condition"] for t in glance["trial_times"]} == {"none", "basic", "full"}
    assert all(t["q1"] <= t["median"] <= t["q3"] for t in glance["trial_times"])
    assert glance["flags"] == [("2026-12-01", {"raised": 2, "cleared": 1})]  # raised that day; cleared that day


def test_each_plot_is_an_svg_image_an_admin_gets(studied):
    c = admin(studied)
    for name in plots.DRAW:
        r = c.get(f"/admin/demo/plots/{name}.svg")
        assert r.status_code == 200 and r.mimetype == "image/svg+xml"
        assert r.headers["Content-Security-Policy"] == "default-src 'none'; style-src 'unsafe-inline'"
        root = ET.fromstring(r.data)
        assert root.tag == f"{SVG}svg"
        assert not list(root.iter(f"{SVG}script")) and len(list(root.iter(f"{SVG}text"))) > 3
    assert c.get("/admin/demo/plots/nothing.svg").status_code == 404
    assert c.get("/admin/nowhere/plots/flags.svg").status_code == 404
    assert studied.test_client().get("/admin/demo/plots/flags.svg").status_code == 302  # to the login


def test_the_dashboard_shows_the_plots_with_their_numbers_as_tables(studied):
    page = admin(studied).get("/admin/").get_data(as_text=True)
    for name in plots.DRAW:
        assert f'src="/admin/demo/plots/{name}.svg"' in page
    assert page.count("<img") == len(plots.DRAW) and page.count('alt="') >= len(plots.DRAW)
    assert 'id="glance-arrivals"' in page and 'id="glance-trial-times"' in page and 'id="glance-flags"' in page
    assert "<td>2026-12-01</td><td>2</td><td>1</td>" in page


def test_a_study_without_data_draws_empty_plots(tmp_path, demo_resources):
    app = make_app(tmp_path, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    c = admin(app)
    for name in plots.DRAW:
        assert c.get(f"/admin/demo/plots/{name}.svg").status_code == 200
    assert "nobody yet" in c.get("/admin/").get_data(as_text=True)


def test_the_plots_draw_early_in_collection_and_flags_count_when_they_change(tmp_path, demo_resources):
    """While a condition has no trial done yet (the first participants of a Williams design) its boxes are
    missing, not the plot; a flag is open from when it was raised until it was cleared."""
    from study_server.base.models import Trial

    studied = completed_study(tmp_path)  # its own: it changes the trials
    with studied.app_context():
        db.session.query(Trial).filter(Trial.condition != "none").update({"done_at": None})
        db.session.commit()
        study = studied.extensions["studies"]["demo"].study
        assert {t["condition"] for t in plots.glance(study)["trial_times"]} == {"none"}
        assert ET.fromstring(plots.plot_trial_times(study)).tag == f"{SVG}svg"
        flags = plots._flags(study)
        assert [(at.hour, n_open, n_cleared) for at, n_open, n_cleared in plots._flag_changes(flags)] == [
            (10, 1, 0), (11, 2, 0), (12, 1, 1)]


def test_each_condition_has_a_hue_of_its_own_in_the_trial_times(studied):
    """The boxes of the three conditions are drawn in three hues (not shades of one), each box of a condition in
    its hue, and the legend says which."""
    import colorsys
    import re

    with studied.app_context():
        svg = plots.plot_trial_times(studied.extensions["studies"]["demo"].study)
    fills = re.findall(r"fill: (#[0-9a-f]{6})", svg)
    drawn = [c.upper() for c in plots.CONDITION_COLOURS[:3]]
    for colour in drawn:
        assert fills.count(colour.lower()) >= 1 + 3  # the legend's marker and a box per scene
    hues = sorted(colorsys.rgb_to_hls(*(int(c[i:i + 2], 16) / 255 for i in (1, 3, 5)))[0] for c in drawn)
    assert min(b - a for a, b in zip(hues, hues[1:], strict=False)) > 0.08  # apart on the colour wheel
