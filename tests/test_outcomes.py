"""Every way out of a study, for the platform: completing, declining consent, being screened out and leaving each
give their own code and send the participant to the platform's completion URL with it; the admin shows the codes
issued per way out and gives the approval list."""

import csv
import io
from html import unescape

import pytest
from flowhelp import EXIT, auth, csrf, enter, finish_all_trials, to_trials
from integrityhelp import PASSWORD
from werkzeug.security import generate_password_hash

from simulation.walker import CAPABLE_DEVICE
from study_server.base.extensions import db
from study_server.base.models import Participant

PID = "5f3a" + "0" * 20  # Prolific ids: 24 hex digits
PROLIFIC = "https://app.prolific.com/submissions/complete?cc="


def entry(n: int) -> str:
    return f"PROLIFIC_PID={n:024x}&SESSION_ID={n + 1000:024x}"


def platform_link(page) -> str | None:
    html = page.get_data(as_text=True)
    if 'id="platform-link"' not in html:
        return None
    return unescape(html.split('id="platform-link" href="')[1].split('"')[0])


@pytest.fixture
def prolific(tmp_path, backend_url, demo_resources):
    """The demo study as a Prolific study (the completion URL left to its default), on SQLite and PostgreSQL."""
    from demostudy import make_app

    text = demo_resources.read_text().replace('kind = "link"', 'kind = "prolific"')
    text = text.replace('target = "scenes/', f'target = "{demo_resources.parent}/scenes/')
    path = tmp_path / "prolific.toml"
    path.write_text(text)
    return make_app(tmp_path / "app", backend_url, studies=[path],
                    ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))


def test_each_way_out_sends_the_participant_to_prolific_with_its_own_code(prolific):
    app = prolific
    done = app.test_client()
    b = to_trials(done, query=entry(1))
    finish_all_trials(done, b)
    page = done.get("/study/demo/")
    done.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "29", "attempt": "0"})
    assert platform_link(done.get("/study/demo/")) == PROLIFIC + "DEMO-DONE-7F3A"

    declined = app.test_client()
    page = enter(declined, query=entry(2))
    declined.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page)})
    declined.post("/study/demo/consent", data={"csrf_token": csrf(page), "agree": "no"})
    assert platform_link(declined.get("/study/demo/")) == PROLIFIC + "DEMO-NOCONSENT"

    small = app.test_client()
    page = enter(small, query=entry(3))
    small.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page), "width": "800"})
    assert platform_link(small.get("/study/demo/")) == PROLIFIC + "DEMO-SCREENED"

    leaving = app.test_client()
    b = to_trials(leaving, query=entry(4))
    ask = leaving.get("/study/demo/leave")
    assert ask.status_code == 200 and b'data-step="leave"' in ask.data
    assert leaving.post("/study/demo/leave", data={}).status_code == 400  # the form's token is needed
    r = leaving.post("/study/demo/leave", data={"csrf_token": csrf(ask)})
    assert r.status_code == 302
    end = leaving.get("/study/demo/")
    assert b"You have left the study" in end.data and platform_link(end) == PROLIFIC + "DEMO-RETURNED"
    late = leaving.post("/api/events", headers=auth(b), json={"page_id": "p", "events": []})
    assert late.status_code == 410  # the session takes nothing more
    assert leaving.get("/study/demo/leave").status_code == 302  # nothing to leave any more

    with app.app_context():
        statuses = {p.platform_id: (p.status, p.code) for p in db.session.query(Participant)}
    assert statuses == {f"{1:024x}": ("completed", "DEMO-DONE-7F3A"), f"{2:024x}": ("no_consent", "DEMO-NOCONSENT"),
                        f"{3:024x}": ("screened_out", "DEMO-SCREENED"), f"{4:024x}": ("returned", "DEMO-RETURNED")}


def test_the_admin_shows_the_codes_issued_and_gives_the_approval_list(prolific):
    app = prolific
    finished = app.test_client()
    finish_all_trials(finished, to_trials(finished, query=entry(1)))
    page = finished.get("/study/demo/")
    finished.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "29", "attempt": "0"})
    for n in (2, 3):
        c = app.test_client()
        ask = (to_trials(c, query=entry(n)), c.get("/study/demo/leave"))[1]
        c.post("/study/demo/leave", data={"csrf_token": csrf(ask)})
    to_trials(app.test_client(), query=entry(5))  # still in progress

    admin = app.test_client()
    assert admin.get("/admin/demo/approvals.csv").status_code == 302  # admins only
    page = admin.get("/admin/login")
    admin.post("/admin/login", data={"csrf_token": csrf(page), "password": PASSWORD})
    dashboard = admin.get("/admin/").get_data(as_text=True)
    issued = dashboard.split('id="codes-issued"')[1].split("</table>")[0]
    assert "<td>completed</td><td><code>DEMO-DONE-7F3A</code></td><td>1</td>" in issued
    assert "<td>returned</td><td><code>DEMO-RETURNED</code></td><td>2</td>" in issued
    by_condition = dashboard.split('id="trials-by-condition"')[1].split("</table>")[0]
    cells = [row.split("</td><td>") for row in by_condition.split("<tr><td>")[1:]]
    done, open_, unfinished = (sum(int(c[i].split("<")[0]) for c in cells) for i in (1, 2, 3))
    assert (done, open_, unfinished) == (9, 9, 18)  # one finished, one in progress, two who left
    r = admin.get("/admin/demo/approvals.csv")
    assert r.status_code == 200 and r.mimetype == "text/csv"
    rows = list(csv.DictReader(io.StringIO(r.get_data(as_text=True))))
    assert [(row["platform_id"], row["status"], row["code"], row["decision"]) for row in rows] == [
        (f"{1:024x}", "completed", "DEMO-DONE-7F3A", "approve"), (f"{2:024x}", "returned", "DEMO-RETURNED", "return"),
        (f"{3:024x}", "returned", "DEMO-RETURNED", "return"), (f"{5:024x}", "in_progress", "", "pending")]
    assert "session" not in rows[0] and all(row["assignment"] == "" for row in rows)  # Prolific's SESSION_ID resumes
    assert f"{1001:024x}" not in r.get_data(as_text=True)  # a session: it is never written


def test_a_study_without_a_code_for_leaving_still_lets_participants_leave(tmp_path, demo_resources):
    from demostudy import make_app

    text = demo_resources.read_text().replace('returned = "DEMO-RETURNED"\n', "")
    text = text.replace('target = "scenes/', f'target = "{demo_resources.parent}/scenes/')
    path = tmp_path / "older.toml"
    path.write_text(text)
    c = make_app(tmp_path / "app", studies=[path]).test_client()
    to_trials(c)
    ask = c.get("/study/demo/leave")
    c.post("/study/demo/leave", data={"csrf_token": csrf(ask)})
    end = c.get("/study/demo/")
    assert b"You have left the study" in end.data and b"completion-code" not in end.data
