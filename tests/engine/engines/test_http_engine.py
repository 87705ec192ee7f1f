"""The http engine: a real external engine in its own process — a good one and hostile ones (slow, garbage, a
100 MB body, a connection that never closes, a status line dribbled out) — answered strictly, and whatever it
does, the query gets a list within the timeout (the fallback's, with the reason). How a study's condition serves
one is in tests/test_study_engines.py."""

from __future__ import annotations

import subprocess
import sys
import time
from dataclasses import replace

import pytest
from enginehelp import a_query, http_engine

from scenesuggest import engines
from scenesuggest.engines.http import parse_answer
from scenesuggest.engines.protocol import LoadContext
from scenesuggest.errors import SceneSuggestError
from scenesuggest.suggestion.query import ContextQuery


def test_a_good_external_engine_answers(external, demo_priors):
    engine = http_engine(f"{external}/good", demo_priors)
    query = a_query()
    found = engine.suggest(query, "full", top=5)
    allowed = sorted(engine.categories, reverse=True)
    assert found.engine == "http" and found.fallback is None
    assert [s.category for s in found] == allowed[:5]  # what the external engine said, in its order
    assert found[0].terms == {"external": 1.0} and found[0].heading_deg == pytest.approx(90.0, abs=1e-6)
    assert found[0].attachment_face == "bottom" and found[0].models == engine.categories[allowed[0]]
    only = set(allowed[-3:])
    assert {s.category for s in engine.suggest(query, "basic", only=only)} == only  # the query names what it allows


@pytest.mark.parametrize(("path", "reason", "within_s"), [
    ("slow", "no answer within 300 ms", 1.0),
    ("hang", "no answer within 300 ms", 1.0),
    ("drip", "no answer within 300 ms", 1.0),
    ("huge", "answer larger than 1048576 bytes", 1.0),
    ("garbage", "invalid answer: not JSON", 1.0),
    ("nan", "invalid answer: not JSON", 1.0),  # NaN (or 1e999) is not JSON: nothing non-finite gets through
    ("unknown", "suggestions[0].category is not one the query allows", 1.0),
    ("scaled", "suggestions[0].placement is not a rigid transform", 1.0),
    ("many", "5000 suggestions, at most 40", 1.0),
    ("error", "HTTP 500", 1.0),
    ("stream", "answer larger than 1048576 bytes", 1.0),
    ("upside", "suggestions[0].attachment_face is not the face its placement turns to the clicked surface", 1.0),
])
def test_a_hostile_engine_gives_the_fallbacks_list_within_the_timeout(external, demo_priors, path, reason,
                                                                     within_s):
    engine = http_engine(f"{external}/{path}", demo_priors)
    paper = engines.load(engines.configure({}), LoadContext(demo_priors))
    query = a_query()
    started = time.monotonic()
    found = engine.suggest(query, "full", top=10)
    assert time.monotonic() - started < within_s
    assert found.fallback is not None and reason in found.fallback and "127.0.0.1" not in found.fallback
    assert found.engine == "paper"
    assert [s.category for s in found] == [s.category for s in paper.suggest(query, "full", top=10)]
    assert engine.fallbacks == 1 and engine.last_server_ms() is None


def test_the_same_engine_answers_again_after_a_failure(external, demo_priors):
    engine = http_engine(f"{external}/flaky?k=recovery", demo_priors)
    answers = [engine.suggest(a_query(), "full", top=3) for _ in range(4)]
    assert [a.fallback for a in answers] == ["HTTP 500", None, "HTTP 500", None]
    assert [a.engine for a in answers] == ["paper", "http", "paper", "http"]


def test_a_connection_the_engine_closed_while_idle_is_not_a_failure(external, demo_priors):
    """Servers close kept-alive connections after a few idle seconds; participants click less often than that."""
    engine = http_engine(f"{external}/idle-close", demo_priors)
    for _ in range(3):
        assert engine.suggest(a_query(), "full", top=3).fallback is None
        time.sleep(0.4)  # the engine has closed the connection meanwhile


def test_a_tls_engine_that_never_shakes_hands_is_timed_out(demo_priors):
    import socket

    with socket.socket() as listening:  # the kernel accepts the connection; nobody ever answers the handshake
        listening.bind(("127.0.0.1", 0))
        listening.listen(8)
        engine = http_engine(f"https://127.0.0.1:{listening.getsockname()[1]}/", demo_priors)
        started = time.monotonic()
        found = engine.suggest(a_query(), "full", top=3)
        assert time.monotonic() - started < 1.0 and found.fallback == "no answer within 300 ms"


def test_no_engine_listening_is_a_fallback_too(demo_priors):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    found = http_engine(f"http://127.0.0.1:{port}/", demo_priors).suggest(a_query(), "basic", top=3)
    assert found.fallback.startswith("connection failed") and len(found) == 3


def test_connections_are_kept_alive(external, demo_priors):
    import json
    import urllib.request

    def connections() -> int:
        with urllib.request.urlopen(f"{external}/count", data=b"{}") as r:
            return json.loads(r.read())["connections"]

    engine = http_engine(f"{external}/good", demo_priors)
    before = connections()
    for _ in range(20):
        assert engine.suggest(a_query(), "full", top=3).fallback is None
    assert connections() - before == 2  # one for the engine's twenty queries, one for the count itself


def test_a_bad_query_is_still_the_participants_error(external, demo_priors):
    engine = http_engine(f"{external}/good", demo_priors)
    query = a_query()
    with pytest.raises(SceneSuggestError) as info:
        engine.suggest(ContextQuery(query.scene, "nobody", query.point, query.normal), "full")
    assert info.value.field == "parent"


def test_answers_are_checked_strictly():
    from scenesuggest.engines.http import NoUsableAnswer

    point, normal = (1.0, 0.75, 2.0), (0.0, 1.0, 0.0)
    upright = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1.0, 0.75, 2.0, 1]
    models = {"Mug": ("m1", "m2"), "Lamp": ("l1",)}

    def problem(doc) -> str:
        from scenesuggest.engines.http import NoUsableAnswer

        with pytest.raises(NoUsableAnswer) as info:
            parse_answer(doc, {"Mug", "Lamp"}, models, point, normal, 3)
        return str(info.value)

    ok = parse_answer({"suggestions": [{"category": "Mug", "score": 2, "placement": upright, "models": ["m2"]}]},
                      {"Mug", "Lamp"}, models, point, normal, 3)
    assert ok[0].models == ("m2",) and ok[0].attachment_face == "bottom" and ok[0].rank == 1
    item = {"category": "Mug", "score": 1, "placement": upright}
    assert "expected" in problem([item])
    assert "appears twice" in problem({"suggestions": [item, item]})
    assert "4 suggestions, at most 3" in problem({"suggestions": [item] * 4})
    # a placeholder is refused even where the query would allow it (a library that named a model "Unknown")
    with pytest.raises(NoUsableAnswer, match=r"suggestions\[0\].category 'Unknown' is a placeholder"):
        parse_answer({"suggestions": [{**item, "category": "Unknown"}]}, {"Unknown", "Mug"},
                     {**models, "Unknown": ("u1",)}, point, normal, 3)
    assert "score" in problem({"suggestions": [{**item, "score": True}]})
    assert "16 finite numbers" in problem({"suggestions": [{**item, "placement": upright[:15]}]})
    assert "16 finite numbers" in problem({"suggestions": [{**item, "placement": [*upright[:15], "1"]}]})
    mirrored = [-1, 0, 0, 0, *upright[4:]]
    assert "rigid" in problem({"suggestions": [{**item, "placement": mirrored}]})
    far = [*upright[:12], 500.0, 0.75, 2.0, 1]
    assert "100 m" in problem({"suggestions": [{**item, "placement": far}]})
    assert "models" in problem({"suggestions": [{**item, "models": ["l1"]}]})
    assert "attachment_face" in problem({"suggestions": [{**item, "attachment_face": "side"}]})
    assert "terms" in problem({"suggestions": [{**item, "terms": {"x": "big"}}]})
    assert "heading_deg" in problem({"suggestions": [{**item, "heading_deg": float("inf")}]})


@pytest.mark.parametrize(("table", "key", "words"), [
    ({"name": "http"}, "url", "missing"),
    ({"name": "http", "url": "ftp://x.org/"}, "url", "http:// or https://"),
    ({"name": "http", "url": "https://user:pw@x.org/"}, "url", "no credentials"),
    ({"name": "http", "url": "http://x.org:99999/"}, "url", "port"),
    ({"name": "http", "url": "http://x.org/", "timeout_ms": 0}, "timeout_ms", "from 1 to 2000"),
    ({"name": "http", "url": "http://x.org/a b"}, "url", "without spaces or control characters"),
    ({"name": "http", "url": "http://x.org/", "timeout_ms": 1.5}, "timeout_ms", "integer"),
    ({"name": "http", "url": "http://x.org/", "fallback": "http"}, "fallback", "other than http"),
    ({"name": "http", "url": "http://x.org/", "fallback": "psychic"}, "fallback.name", "unknown engine"),
    ({"name": "http", "url": "http://x.org/", "fallback": {"name": "paper", "lambda2": -1}}, "fallback.lambda2", "≥ 0"),
    ({"name": "http", "url": "http://x.org/", "retries": 3}, "retries", "unknown key"),
    ({"name": "psychic"}, "name", "unknown engine 'psychic'"),
    ({"name": 5}, "name", "expected the name of an engine"),
    ({"name": "learned", "file": ""}, "file", "path"),
    ({"name": "frequency", "lambda1": 2}, "lambda1", "unknown key"),
])
def test_engine_tables_are_validated_naming_the_key(table, key, words):
    with pytest.raises(SceneSuggestError) as info:
        engines.configure(table)
    assert info.value.field == key and words in info.value.message


# --- through the study server ---------------------------------------------------------------------------------


def test_a_failing_engine_stops_costing_its_timeout_and_is_tried_again_later(external, demo_priors, monkeypatch):
    """Three timeouts in a row open the circuit: the next queries get the fallback's list at once; after the open
    time one query probes the engine (a failure opens it again for twice as long); an answer closes it. Each
    opening and closing is told to on_change."""
    from scenesuggest.engines import http

    monkeypatch.setattr(http, "BREAKER_OPEN_S", 0.5)
    engine = http_engine(f"{external}/hang", demo_priors)
    heard = []
    engine.breaker.on_change = lambda state, detail: heard.append((state, detail))

    def timed():
        started = time.monotonic()
        found = engine.suggest(a_query(), "full", top=3)
        return time.monotonic() - started, found.fallback

    paid = [timed() for _ in range(3)]
    assert all(s >= 0.29 and reason == "no answer within 300 ms" for s, reason in paid)
    assert heard == [("open", {"reason": "no answer within 300 ms", "failures": 3, "retry_s": 0.5})]
    for _ in range(20):
        took, reason = timed()
        assert took < 0.1 and reason.startswith("the engine failed 3 times in a row: not asked for")
    time.sleep(0.55)
    took, reason = timed()  # the probe: the engine still hangs
    assert took >= 0.29 and reason == "no answer within 300 ms" and heard[-1][1]["retry_s"] == 1.0
    engine.options = replace(engine.options, url=f"{external}/good")
    engine._path = "/good"
    time.sleep(1.05)
    assert timed()[1] is None and heard[-1] == ("closed", {})  # it answers again: closed
    assert timed()[1] is None and len(heard) == 3


def test_only_one_query_probes_an_open_circuit_while_the_others_fall_back():
    from scenesuggest.engines.http import BREAKER_FAILURES, Breaker

    now = [0.0]
    breaker = Breaker(clock=lambda: now[0])
    for _ in range(BREAKER_FAILURES - 1):
        breaker.record("HTTP 500")
    assert breaker.refusal() is None and breaker.state == "closed"  # not yet
    breaker.record("HTTP 500")
    assert breaker.state == "open" and "3 times in a row" in breaker.refusal()
    now[0] = 10.0
    assert breaker.refusal() is None and breaker.state == "probing"  # the first query after the open time probes
    assert breaker.refusal() == "the engine failed: another query is trying it again"
    breaker.record(None)
    assert breaker.state == "closed" and breaker.failures == 0 and breaker.refusal() is None


def test_a_scene_piled_high_is_sent_summarised_so_a_participant_cannot_slow_the_engine():
    """2,500 objects on the floor: the query carries 400 — the clicked table, what supports it, what stands on it,
    then the objects nearest the click — each with what supports it, and says how many it left out."""
    import numpy as np

    from scenesuggest.engines.wire import MAX_QUERY_OBJECTS, query_scene
    from scenesuggest.scenes.scene import ObjectInstance, Scene

    def at(x, z, y=0.0):
        t = np.eye(4)
        t[:3, 3] = (x, y, z)
        return t

    objects = {"room": ObjectInstance("room", "r", "Room", np.eye(4), (20.0, 3.0, 20.0)),
               "table": ObjectInstance("table", "t", "Table", at(9.0, 9.0), (1.0, 0.7, 1.0), parent="room"),
               "cup": ObjectInstance("cup", "c", "Cup", at(9.0, 9.0, 0.7), (0.1, 0.1, 0.1), parent="table")}
    for i in range(2500):
        objects[f"box{i}"] = ObjectInstance(f"box{i}", "b", "Box", at(i % 50 * 0.3, i // 50 * 0.3), (0.2, 0.2, 0.2),
                                            parent="room")
    scene = Scene("big", "LivingRoom", objects)
    summary, left_out = query_scene(scene, "table", (9.0, 0.7, 9.0))
    assert len(summary) == MAX_QUERY_OBJECTS and left_out == len(scene) - MAX_QUERY_OBJECTS
    assert {"room", "table", "cup"} <= set(summary.objects)
    assert all(o.parent is None or o.parent in summary.objects for o in summary)  # still a scene
    kept = [summary.objects[k].transform[:3, 3] for k in summary.objects if k.startswith("box")]
    dropped = [o.transform[:3, 3] for k, o in scene.objects.items() if k.startswith("box") and k not in summary.objects]
    near = lambda p: np.hypot(p[0] - 9.0, p[2] - 9.0)  # noqa: E731
    assert max(map(near, kept)) <= min(map(near, dropped)) + 1e-9  # the nearest were kept
    small = Scene("small", "LivingRoom", dict(list(objects.items())[:50]))
    assert query_scene(small, "table", (9.0, 0.7, 9.0)) == (small, 0)


def test_waits_on_engines_take_at_most_their_share_of_a_servers_workers(external, demo_priors, tmp_path):
    """One slot, held by another process (another worker waiting on an engine): a query falls back at once, as
    busy, without counting against the engine; once that process is gone (killed: the kernel drops its lock), the
    engine is asked again."""
    from scenesuggest.engines.http import WaitSlots

    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time\nfrom scenesuggest.engines.http import WaitSlots\n"
        "with WaitSlots(sys.argv[1], 1).held() as free:\n    print(free, flush=True)\n    time.sleep(60)\n"),
        str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "True"
        engine = http_engine(f"{external}/good", demo_priors)
        engine.slots = WaitSlots(tmp_path, 1)
        started = time.monotonic()
        found = engine.suggest(a_query(), "full", top=3)
        assert time.monotonic() - started < 0.2 and found.engine == "paper"
        assert found.fallback == "the engine is busy: 1 queries of this server already wait on engines"
        assert engine.breaker.failures == 0  # busy is not the engine's failure
        with WaitSlots(tmp_path, 2).held() as free:  # a second slot is free
            assert free
    finally:
        holder.kill()
        holder.wait()
    assert engine.suggest(a_query(), "full", top=3).fallback is None


@pytest.mark.parametrize("path", ["close", "http10"])
def test_an_answer_that_closes_its_connection_is_an_answer(external, demo_priors, path):
    """Connection: close, or HTTP/1.0 as Python's http.server answers (the end of the body the connection's
    close): valid answers within the deadline, used, again and again."""
    engine = http_engine(f"{external}/{path}", demo_priors)
    for _ in range(3):
        found = engine.suggest(a_query(), "full", top=3)
        assert found.fallback is None and found.engine == "http" and len(found) == 3


def test_a_query_that_never_reaches_the_engine_never_takes_the_probe(external, demo_priors, tmp_path):
    """The circuit's open time is over, but every wait slot is taken: the query falls back as busy and the next
    one that gets a slot is the probe — the circuit is not left waiting for a probe that never went."""
    from scenesuggest.engines.http import BREAKER_FAILURES, Breaker, WaitSlots

    now = [0.0]
    engine = http_engine(f"{external}/good", demo_priors)
    engine.breaker = Breaker(clock=lambda: now[0])
    for _ in range(BREAKER_FAILURES):
        engine.breaker.record("HTTP 500")
    now[0] = 60.0
    engine.slots = WaitSlots(tmp_path, 1)
    with engine.slots.held() as free:  # another worker waits on an engine meanwhile
        assert free
        assert engine.suggest(a_query(), "full", top=3).fallback.startswith("the engine is busy")
    assert engine.breaker.state == "open"
    found = engine.suggest(a_query(), "full", top=3)  # the probe
    assert found.fallback is None and engine.breaker.state == "closed"
    engine.slots = WaitSlots(tmp_path / "taken-by-a-cleaner" / "gone", 1)
    assert engine.suggest(a_query(), "full", top=3).fallback is None  # a lost folder is made again
