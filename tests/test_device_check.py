"""The device check on the server (study_server.participants.device): a browser that cannot run the trial is screened
out before consent, with its reasons, holding no schedule row; a report no browser sends is refused (422, naming the
field) and stores nothing; nobody gets past the check by posting to the steps after it."""

from __future__ import annotations

import csv
import io
import zipfile

import pytest
from flowhelp import csrf, enter
from integrityhelp import PASSWORD
from werkzeug.security import generate_password_hash

from simulation.walker import CAPABLE_DEVICE
from study_server.base.extensions import db
from study_server.base.models import Participant, SessionLog


def _arrive(app, pid: str):
    c = app.test_client()
    page = enter(c, query=f"pid={pid}")
    return c, csrf(page)


def _stored(app, pid: str) -> tuple[Participant, int]:
    with app.app_context():
        p = db.session.query(Participant).filter_by(platform_id=pid).one()
        checks = db.session.query(SessionLog).filter_by(participant_id=p.id, kind="device_check").count()
        db.session.expunge(p)
        return p, checks


@pytest.mark.parametrize("field,value,named", [
    ("fps", "1e9", "fps"), ("fps", "-1", "fps"), ("fps", "nan", "fps"), ("fps", "inf", "fps"), ("fps", "", "fps"),
    ("width", "-900", "width"), ("width", "1" + "0" * 30, "width"), ("height", "12.5", "height"),
    ("height", "٣٠٠", "height"), ("pixel_ratio", "0", "pixel_ratio"), ("pixel_ratio", "99", "pixel_ratio"),
    ("touch_only", "maybe", "touch_only"), ("missing", "webgl2,teleport", "missing"),
    ("missing", "webgl2,webgl2", "missing"), ("missing", "x" * 10_000, "missing"),
    ("renderer", "r" * 201, "renderer"), ("renderer", "GPU\x00\x1b[31m", "renderer"),
])
def test_a_report_no_browser_sends_is_refused_naming_the_field_and_nothing_is_stored(app, field, value, named):
    c, token = _arrive(app, "liar")
    r = c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": token, field: value})
    assert r.status_code == 422, r.data
    assert named.encode() in r.data and b"Traceback" not in r.data
    p, checks = _stored(app, "liar")
    assert (p.step, p.status, p.viewport, p.row, checks) == ("device", "in_progress", None, -1, 0)


@pytest.mark.parametrize("field,raw", [
    ("missing", "webgl2%00"), ("fps", "60%00"), ("width", "1280%00"), ("renderer", "GPU%00"),
    ("missing", "webgl2%ED%A0%80"), ("fps", "60%ED%A0%80"), ("touch_only", "false%C0%80"),
])
def test_bytes_no_browser_form_holds_are_refused_naming_the_field(app, field, raw):
    """A NUL after a good value, or bytes that are not UTF-8 (a UTF-16 surrogate, an overlong NUL) after one, sent
    raw: Werkzeug decodes the NUL and keeps invalid UTF-8 percent-escaped, so each reaches the check as a value that
    is good up to the bytes added, and must be refused."""
    from urllib.parse import urlencode

    c, token = _arrive(app, "raw")
    body = urlencode({**{k: v for k, v in CAPABLE_DEVICE.items() if k != field}, "csrf_token": token})
    r = c.post("/study/demo/device", data=f"{body}&{field}={raw}",
               content_type="application/x-www-form-urlencoded")
    assert r.status_code == 422, r.data
    assert field.encode() in r.data and b"Traceback" not in r.data
    p, checks = _stored(app, "raw")
    assert (p.step, p.viewport, p.row, checks) == ("device", None, -1, 0)


@pytest.mark.parametrize("left_out", sorted(CAPABLE_DEVICE))
def test_a_report_without_a_field_is_refused(app, left_out):
    c, token = _arrive(app, "short")
    data = {k: v for k, v in CAPABLE_DEVICE.items() if k != left_out}
    r = c.post("/study/demo/device", data={**data, "csrf_token": token})
    if left_out == "renderer":  # optional: not every browser names its GPU
        assert r.status_code == 302
        return
    assert r.status_code == 422 and left_out.encode() in r.data
    assert _stored(app, "short")[0].viewport is None


def test_a_frame_rate_from_a_browser_that_could_not_draw_is_refused(app):
    c, token = _arrive(app, "odd")
    r = c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": token, "missing": "webgl2", "fps": "60"})
    assert r.status_code == 422 and b"fps" in r.data


def test_ten_megabytes_of_report_get_413_and_nothing_is_stored(app):
    c, token = _arrive(app, "huge")
    r = c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": token, "renderer": "x" * 10_000_000})
    assert r.status_code == 413 and b"Traceback" not in r.data
    assert _stored(app, "huge")[0].viewport is None


@pytest.mark.parametrize("report,reasons,says", [
    ({"missing": "webgl2", "fps": ""}, ["webgl2"], b"WebGL 2 is switched off"),
    ({"missing": "storage"}, ["storage"], b"storage is blocked"),
    ({"missing": "importmap", "fps": ""}, ["importmap"], b"import maps"),
    ({"missing": "shaders", "fps": "", "renderer": "llvmpipe"}, ["shaders"], b"could not draw the editor"),
    ({"fps": "3.25"}, ["slow"], b"drew 3.2 frames a second; the 3D editor needs at least 10"),
    ({"width": "900", "fps": "4"}, ["window", "slow"], b"The browser window is 900 \xc3\x97 900 pixels"),
    ({"missing": "script", "width": "0", "height": "0", "fps": ""}, ["script"], b"JavaScript is switched off"),
])
def test_a_browser_that_cannot_run_the_editor_is_screened_out_with_its_reasons_and_takes_no_row(
        app, report, reasons, says):
    c, token = _arrive(app, "unable")
    r = c.post("/study/demo/device", data={**CAPABLE_DEVICE, "height": "900", "csrf_token": token, **report})
    assert r.status_code == 302
    page = c.get("/study/demo/")
    assert says in page.data and b"DEMO-SCREENED" in page.data and b"up-to-date Chrome" in page.data
    p, checks = _stored(app, "unable")
    assert (p.status, p.row, p.viewport["reasons"], checks) == ("screened_out", -1, reasons, 1)
    # nothing after the check is open to it
    assert c.post("/study/demo/consent", data={"csrf_token": token, "agree": "yes"}).status_code == 302
    assert _stored(app, "unable")[0].row == -1


def test_the_end_page_says_it_in_the_participants_language(app):
    c = app.test_client()
    c.get("/study/demo/start?pid=de-1", headers={"Accept-Language": "de"})
    page = c.get("/study/demo/")
    c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page), "missing": "webgl2", "fps": ""})
    text = c.get("/study/demo/").data.decode()
    assert "WebGL 2 ist ausgeschaltet" in text and "DEMO-SCREENED" in text


def test_posting_past_the_check_moves_nothing(app):
    c, token = _arrive(app, "skipper")
    for step, data in (("consent", {"agree": "yes"}), ("demographics", {"age": "30"}),
                       ("instructions", {"go": "next"})):
        c.post(f"/study/demo/{step}", data={"csrf_token": token, **data})
    p, _ = _stored(app, "skipper")
    assert (p.step, p.row) == ("device", -1)
    assert b"device-form" in c.get("/study/demo/").data


def test_screened_out_browsers_leave_the_latin_square_balanced_and_are_counted_by_reason(app):
    from flowhelp import DEMOGRAPHICS

    for k in range(3):  # three browsers without WebGL arrive first
        c, token = _arrive(app, f"no-gl-{k}")
        c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": token, "missing": "webgl2", "fps": ""})
    rows = []
    for k in range(6):
        c, token = _arrive(app, f"able-{k}")
        c.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": token})
        c.post("/study/demo/consent", data={"csrf_token": token, "agree": "yes"})
        c.post("/study/demo/demographics", data={"csrf_token": token, **DEMOGRAPHICS})
        rows.append(_stored(app, f"able-{k}")[0].row)
    assert rows == [0, 1, 2, 3, 4, 5]  # as if the screened-out had never come
    app.config["ADMIN_PASSWORD_HASH"] = generate_password_hash(PASSWORD)
    admin = app.test_client()
    admin.post("/admin/login", data={"csrf_token": csrf(admin.get("/admin/login")), "password": PASSWORD})
    dashboard = admin.get("/admin/")
    assert b"screened out 3" in dashboard.data and b"webgl2 3" in dashboard.data
    export = admin.get("/admin/demo/export.zip")
    with zipfile.ZipFile(io.BytesIO(export.data)) as z:
        name = next(n for n in z.namelist() if n.endswith("participants.csv"))
        rows = list(csv.DictReader(io.StringIO(z.read(name).decode())))
    assert sorted(r["screened_out_reasons"] for r in rows) == ["", "", "", "", "", "", "webgl2", "webgl2", "webgl2"]
    assert all(float(r["device_fps"]) == 60 for r in rows if not r["screened_out_reasons"])
