"""Walking a participant through a study in tests (Flask test client), with the simulation's one walker."""

from __future__ import annotations

from simulation.page import read_page
from simulation.transport import FlaskTransport
from simulation.walker import Walker

DEMOGRAPHICS = {"age": "31", "experience_3d": "Never", "pointing_device": "Trackpad"}
EXIT = {"enjoy_list": "2", "competent_list": "3", "enjoy_suggestions": "5", "competent_suggestions": "4",
        "preference": "Suggestions, oriented", "comments": "<script>alert('x')</script> nice"}


def csrf(response) -> str:
    """The form token of a page (a test client's response)."""
    return read_page(response.data).csrf


def boot(response) -> dict:
    """The scene editor's boot data of a trial page (a test client's response)."""
    return read_page(response.data).boot


def enter(client, study="demo", query="pid=p1", ua="Mozilla/5.0 (X11; Linux x86_64) Chrome/150"):
    r = client.get(f"/study/{study}/start?{query}", headers={"User-Agent": ua})
    assert r.status_code == 302, r.data
    return client.get(f"/study/{study}/")


def to_trials(client, study="demo", query="pid=p1") -> dict:
    """From the entry link to the first trial page; returns the trial page's boot data."""
    walker = Walker(FlaskTransport(client), study)
    page = walker.enter(query, headers={"User-Agent": "Mozilla/5.0 (X11; Linux x86_64) Chrome/150"})
    client.form_token = page.csrf  # the browser session's form token, for later posts
    page = walker.walk(lambda _: DEMOGRAPHICS, page=page)
    assert page.step == "trial", f"never reached the trials (stopped at {page.step!r})"
    return page.boot


def next_trial(client, study="demo") -> dict:
    """The boot data of the participant's current trial page (past the page of its condition's instructions, when
    one is due)."""
    page = Walker(FlaskTransport(client), study).walk(lambda _: DEMOGRAPHICS)
    assert page.step == "trial", f"not at a trial (at {page.step!r})"
    return page.boot


def auth(b: dict) -> dict:
    return {"Authorization": f"Bearer {b['token']}"}


def finish_all_trials(client, b: dict, study="demo", first_seq: int = 0) -> list[dict]:
    """Work through every trial (events numbered from ``first_seq``): a trial_start, one object inserted, a
    trial_done 12 s later, and 'done'; returns each trial's boot data."""
    seen, seq = [], first_seq

    def trial(b: dict) -> bool:
        nonlocal seq
        seen.append(b)
        t = b["trial"]
        t0 = 1.0e12 + seq * 1.0e5
        events = [{"seq": seq, "t": t0, "type": "trial_start", "trial": t["index"],
                   "payload": {"scene": t["scene"], "condition": t["condition"]}},
                  {"seq": seq + 1, "t": t0 + 5000, "type": "insert", "trial": t["index"],
                   "payload": {"object": f"o{seq}", "model": "m", "category": "Chair", "rank": None,
                               "source": "fixed"}},
                  {"seq": seq + 2, "t": t0 + 12000, "type": "trial_done", "trial": t["index"],
                   "payload": {"objects": 1}}]
        seq += 3
        r = client.post("/api/events", headers=auth(b), json={"page_id": b["page_id"], "events": events})
        assert r.status_code == 200 and r.json["acked_seq"] == seq - 1, r.json
        r = client.post("/api/trial/done", headers=auth(b), json={"trial": t["index"]})
        assert r.status_code == 200, r.json
        return True

    trial(b)
    Walker(FlaskTransport(client), study).walk(lambda _: DEMOGRAPHICS, trial, until=("exit",))
    return seen
