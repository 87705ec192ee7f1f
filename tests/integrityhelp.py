"""What the integrity tests share: the admin password and platform ids they use, the demo study with another
platform or other limits, a participant as stored, and events posted as the page posts them. (The ``app_on``
fixture, the app on SQLite and on PostgreSQL with this admin password, is in conftest.py.)"""

from __future__ import annotations

from demostudy import DEMO_STUDY
from flowhelp import auth

from study_server.base.extensions import db
from study_server.base.models import Participant

PASSWORD = "correct horse battery staple"
PID, STUDY, SESSION = "5f3a" + "0" * 20, "6a1b" + "1" * 20, "7c2d" + "2" * 20


def study_copy(tmp_path, name="study", platform=None, **limits):
    """The demo study file with another platform and other limits (its scenes and resources still the demo's)."""
    text = DEMO_STUDY.read_text()
    text = text.replace('target = "scenes/', f'target = "{DEMO_STUDY.parent}/scenes/')
    if platform:
        text = text.replace('kind = "link"', f'kind = "{platform}"\nstudy_id = "{STUDY}"')
    for key, value in limits.items():
        text = text.replace("[limits]\n", f"[limits]\n{key} = {value}\n") if f"\n{key} =" not in text else \
            __import__("re").sub(rf"\n{key} = [^\n]*", f"\n{key} = {value}", text)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def participant_of(app, platform_id) -> Participant:
    with app.app_context():
        p = db.session.query(Participant).filter_by(platform_id=platform_id).one()
        db.session.expunge(p)
        return p


def post_events(c, b, events, page_id=None):
    return c.post("/api/events", headers=auth(b), json={"page_id": page_id or b["page_id"], "events": events})


def event(seq, type_="search", trial=0, t=None, **payload):
    return {"seq": seq, "t": t if t is not None else 1.0e12 + seq, "type": type_, "trial": trial,
            "payload": payload or {"text": f"query {seq}"}}
