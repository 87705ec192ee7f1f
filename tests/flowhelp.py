"""Walking a participant through a study with HTTP requests alone (Flask test client)."""

from __future__ import annotations

import html
import json
import re

DEMOGRAPHICS = {"age": "31", "experience_3d": "Never", "pointing_device": "Trackpad"}
EXIT = {"enjoy_list": "2", "competent_list": "3", "enjoy_suggestions": "5", "competent_suggestions": "4",
        "preference": "Suggestions, oriented", "comments": "<script>alert('x')</script> nice"}


def csrf(response) -> str:
    return re.search(rb'name="csrf_token" value="([^"]+)"', response.data).group(1).decode()


def boot(response) -> dict:
    raw = re.search(rb'<script type="application/json" id="boot">(.*?)</script>', response.data, re.S).group(1)
    return json.loads(html.unescape(raw.decode()))


def enter(client, study="demo", query="pid=p1", ua="Mozilla/5.0 (X11; Linux x86_64) Chrome/150"):
    r = client.get(f"/study/{study}/start?{query}", headers={"User-Agent": ua})
    assert r.status_code == 302, r.data
    return client.get(f"/study/{study}/")


def to_trials(client, study="demo", query="pid=p1") -> dict:
    """From the entry link to the first trial page; returns the trial page's boot data."""
    page = enter(client, study, query)
    token = csrf(page)
    client.form_token = token  # the browser session's form token, for later posts
    client.post(f"/study/{study}/device", data={"csrf_token": token, "width": "1400", "height": "900"})
    client.post(f"/study/{study}/consent", data={"csrf_token": token, "agree": "yes"})
    client.post(f"/study/{study}/demographics", data={"csrf_token": token, **DEMOGRAPHICS})
    for _ in range(10):
        page = client.get(f"/study/{study}/")
        if b'id="boot"' in page.data:
            return boot(page)
        client.post(f"/study/{study}/instructions", data={"csrf_token": token, "go": "next"})
    raise AssertionError("never reached the trials")


def auth(b: dict) -> dict:
    return {"Authorization": f"Bearer {b['token']}"}


def finish_all_trials(client, b: dict, study="demo") -> list[dict]:
    """Work through every trial: a trial_start, one object inserted, a trial_done 12 s later, and 'done';
    returns each trial's boot data."""
    seen, seq = [], 0
    while True:
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
        page = client.get(f"/study/{study}/")
        if b'id="boot"' not in page.data:
            return seen
        b = boot(page)
