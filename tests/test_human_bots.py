"""Simulated participants that behave like people, their calibration on some of the paper's conditions, and
what each condition can tell of them."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from demostudy import DEMO_STUDY, copy_demo_study, make_app
from support import ROOT

from scenesuggest.errors import SceneSuggestError
from simulation import calibrate, paper_tables
from simulation.calibrate import Rehearsal, explain, explain_lines, fit, loss, measure, read, write
from simulation.human import Human, describe, free_parameters, used_in
from simulation.paper_tables import CONDITIONS, TABLE1, cells, conditions_of
from simulation.participant import Bot
from simulation.transport import FlaskTransport


def test_every_parameter_is_named_with_its_unit_range_and_source():
    rows = describe()
    assert {r["name"] for r in rows} == {f.name for f in fields(Human)}
    for r in rows:
        assert r["unit"] and len(r["source"]) > 20 and r["low"] <= r["default"] <= r["high"], r
    assert 8 <= len(free_parameters()) < len(rows)  # the interface and the literature fix the rest


@pytest.mark.parametrize(("values", "message"), [
    ({"hesitation_s": float("nan")}, "field 'hesitation_s': expected a finite number"),
    ({"overlook": 1.5}, "field 'overlook': 1.5 is outside [0.0, 0.9] (probability)"),
    ({"scan_item_s": "fast"}, "field 'scan_item_s': expected a number, got 'fast'"),
    ({"patience": 3}, "no behaviour parameter 'patience'"),
])
def test_bad_parameters_are_named(values, message):
    with pytest.raises(SceneSuggestError, match=re.escape(message)):
        Human().with_values(values)


def test_practice_wears_off_and_scenes_are_alike_for_everyone():
    h = Human(practice=0.5, practice_halving=2.0)
    assert h.practice_factor(0) == 1.5 and h.practice_factor(2) == 1.25 and h.practice_factor(20) < 1.001
    a, b = (Bot(None, "demo", pid, np.random.default_rng(k), human=h, scene_seed=3) for k, pid in enumerate("ab"))
    assert a.scene_factor("desk") == b.scene_factor("desk") != a.scene_factor("bedside")
    assert a.speed != b.speed  # people differ


@pytest.fixture(scope="module")
def rehearsal(tmp_path_factory, demo_resources):
    return Rehearsal(make_app(tmp_path_factory.mktemp("rehearsal")), "demo", participants=4, seed=0)


def test_a_rehearsal_measures_the_none_condition_as_the_analysis_does(rehearsal):
    events = rehearsal.events(Human())
    measured = measure(events)
    assert set(measured) >= set(TABLE1) | {"total_time_se"} and all(math.isfinite(v) for v in measured.values())
    assert set(events["condition"]) == {"none"}  # only the rehearsal's conditions are played
    assert abs(sum(measured[f"rank_{k}"] for k in ("1", "2", "3", "4+")) - 1) < 1e-9
    assert (events["type"] == "camera").any() and (events["type"] == "search").any()  # looks round, searches
    moves = events[events["type"] == "move_end"].groupby(["participant", "trial"])["payload"].apply(
        lambda p: max(np.unique([x["object"] for x in p], return_counts=True)[1]))
    assert moves.max() > 1  # a drag that missed was corrected
    # common random numbers: the same people and parameters give the same events; slower scanning, more time
    assert measure(rehearsal.events(Human())) == measured
    slower = measure(rehearsal.events(Human(scan_item_s=1.0, list_patience=100, search_first=0.0)))
    assert slower["total_time"] > measured["total_time"] and slower["rank_4+"] > measured["rank_4+"]


def test_people_search_with_their_own_words_and_reformulate(rehearsal, demo_resources):
    app = make_app(Path(rehearsal.app.instance_path).parent / "words")
    bot = Bot(FlaskTransport(app.test_client()), "demo", "w", np.random.default_rng(0),
              human=Human(category_words=0.0, unknown_words=0.0))
    bot.library = {"m": {"id": "m", "name": "Tall Lamp 3000", "tags": ["light"],
                         "category_path": ["Lighting", "FloorLamp"]}}
    from simulation.actions import BotTrial

    trial = BotTrial(bot, {"token": "", "page_id": "p", "vocabulary": 2, "batch": 200,
                        "trial": {"index": 0, "scene": "desk", "condition": "none", "kind": "trial"}})
    texts = trial.search_texts({"model_id": "m", "category": "FloorLamp"})
    assert texts[0] in ("tall", "tall lamp") and "floor lamp" in texts and "lighting" in texts
    trial.human = Human(category_words=0.0, tag_words=1.0, unknown_words=0.0)  # what it is for: models share it
    assert trial.search_texts({"model_id": "m", "category": "FloorLamp"})[0] == "light"
    trial.human = Human(category_words=1.0, generic_words=0.0, unknown_words=1.0)  # a typo first, then the words
    typo, *rest = trial.search_texts({"model_id": "m", "category": "FloorLamp"})
    assert rest[0] == "floor lamp" and typo != "floor lamp" and sorted(typo) == sorted("floor lamp")


@pytest.mark.parametrize(("text", "u", "typed"), [("desk lamp", 0.0, "dsek lamp"), ("book", 0.0, "bok"),
                                                  ("mug", 0.9, "mgu"), ("coffee table", 0.99, "coffe table")])
def test_a_typo_swaps_two_letters_after_the_first(text, u, typed):
    from simulation.actions import misspelt

    assert misspelt(text, u) == typed


def test_trackpad_users_drag_slower(tmp_path, demo_resources):
    rehearsal = Rehearsal(make_app(tmp_path / "app"), "demo", participants=3, seed=0)
    mouse = measure(rehearsal.events(Human(trackpad_share=0.0)))
    pads = measure(rehearsal.events(Human(trackpad_share=1.0)))
    assert pads["translation_time"] > 1.3 * mouse["translation_time"]
    assert pads["rotation_time"] == mouse["rotation_time"]  # turning is done with keys or the ring alike


def test_the_loss_is_zero_at_the_paper_and_grows_away_from_it():
    fold = cells(("none", "full"))
    at_paper = {c: {} for c in ("none", "full")}
    for cell in fold:
        at_paper[cell.condition][cell.measure] = cell.mean
    assert loss(at_paper, fold) == 0
    off = {**at_paper, "full": {**at_paper["full"], "total_time": 168.0}}  # full's upper bound, 29 s above
    assert loss(off, fold) == pytest.approx((29.0 / ((168.0 - 118.0) / 3.92)) ** 2)
    off = {**at_paper, "none": {**at_paper["none"], "rank_2": 0.140 + 0.10}}  # two RANK_SE
    assert loss(off, fold) == pytest.approx(4.0)
    assert loss({**at_paper, "none": {**at_paper["none"], "mrr": float("nan")}}, fold) == 1e9
    wide = {**at_paper, "none": {**at_paper["none"], "total_time_se": 1.2 * (241.0 - 177.0) / 3.92}}
    assert loss(wide, fold) == pytest.approx(1.0)  # people 20% more spread than the interval says: one SE


@pytest.mark.parametrize(("text", "message"), [
    ("none,basic,full", "a calibration fitted on all three conditions predicts none"),
    ("none,oriented", "no condition 'oriented' in the paper (it has none, basic, full)"),
    ("none,none", "a condition is named twice"),
    ("", "expected conditions separated by commas"),
    ("none,", "expected conditions separated by commas"),
])
def test_a_fold_names_one_or_two_of_the_papers_conditions(text, message):
    with pytest.raises(SceneSuggestError, match=re.escape(message)):
        conditions_of(text)
    assert conditions_of("full, none") == ("none", "full")  # in the paper's order


def test_cells_hand_out_only_the_folds_conditions():
    fold = cells(("basic",))
    assert {c.condition for c in fold} == {"basic"} and len(fold) == len(TABLE1) + 4 + 3
    total = next(c for c in fold if c.measure == "total_time")
    assert (total.mean, total.se) == (170.0, pytest.approx((267.0 - 130.0) / 3.92))
    assert total.matched(267.0) and not total.matched(267.5)
    share = next(c for c in fold if c.measure == "rank_1")
    assert share.matched(0.687 - 0.08) and not share.matched(0.687 - 0.081)
    spread = next(c for c in fold if c.measure == "total_time_se")  # how much people differ, from the width
    assert spread.mean == pytest.approx(total.se) and spread.se == pytest.approx(0.2 * total.se)
    assert spread.table is None and total.table == 1 and share.table == 2


FOLDS = [("none",), ("none", "basic"), ("none", "full"), ("basic", "full")]


@pytest.mark.parametrize("on", FOLDS, ids=["+".join(f) for f in FOLDS])
def test_a_fold_never_reads_the_held_out_conditions(on, demo_resources, tmp_path, monkeypatch):
    """A fit on ``on`` is the same, to the bit, when every held-out cell of the paper's tables says something
    else; its file holds its own conditions' cells only, and it fits exactly the parameters they use."""
    rehearsal = Rehearsal(make_app(tmp_path / "app"), "demo", participants=2, seed=0, conditions=on)

    def fitted() -> dict:
        document = fit(rehearsal, evaluations=2)
        return {k: v for k, v in document.items() if k not in ("seconds", "created")}

    honest = fitted()
    for by in [*paper_tables.TABLE1.values(), *paper_tables.TABLE2.values()]:
        for c in paper_tables.held_out(on):
            monkeypatch.setitem(by, c, (1e6, -1e6, 3e6) if isinstance(by[c], tuple) else 0.999)
    assert fitted() == honest
    assert honest["on"] == list(on) and honest["held_out"] == [c for c in CONDITIONS if c not in on]
    assert {k.split(".")[0] for k in honest["paper"]} == set(on) and set(honest["measured"]) == set(on)
    assert honest["free"] == free_parameters(on)
    assert all(set(used_in(p)) & set(on) for p in honest["free"])
    unused = [p for p in free_parameters() if not set(used_in(p)) & set(on)]
    assert ("suggestion_patience" in unused) == (on == ("none",))
    assert (("list_patience" in unused) and ("search_first" in unused)) == (on == ("basic", "full"))
    assert all(honest["parameters"][p] == getattr(Human(), p) for p in unused)  # kept at their defaults
    # a start fitted elsewhere gives the fold's own parameters only: the others stay at their defaults
    def quarter(p: str) -> float:
        low, high = calibrate.bounds(p)
        return low + 0.25 * (high - low)

    elsewhere = Human().with_values({p: quarter(p) for p in free_parameters()})
    started = fit(rehearsal, evaluations=1, start=elsewhere)
    assert all(started["parameters"][p] == getattr(Human(), p) for p in unused)
    assert all(started["parameters"][p] == pytest.approx(quarter(p)) for p in honest["free"])


def test_the_papers_numbers_live_in_one_module():
    """The bots and their fit hold none of the paper's Table 1 or Table 2 numbers: a fit reaches them only through
    ``paper_tables.cells`` of its own conditions (the test above)."""
    import ast

    numbers = {v for by in TABLE1.values() for cell in by.values() for v in cell}
    numbers |= {v for by in paper_tables.TABLE2.values() for v in by.values()}
    numbers -= {2.5}  # full's keyword queries, and the distance a bot looks round from (metres): not the paper's
    numbers = {v for v in numbers if v != int(v) or v >= 100}  # small whole numbers are everywhere (7 digits, …)
    for name in ("calibrate.py", "human.py", "actions.py", "participant.py", "timing.py", "power.py", "cli.py"):
        tree = ast.parse((ROOT / "simulation" / name).read_text())
        found = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)
                 and isinstance(n.value, int | float) and not isinstance(n.value, bool)}
        assert not found & numbers, (name, found & numbers)


@pytest.mark.parametrize(("parameter", "condition"), [
    (p, c) for p in free_parameters() for c in CONDITIONS if c not in used_in(p)])
def test_a_parameter_a_condition_does_not_use_leaves_its_trials_as_they_were(parameter, condition, tmp_path,
                                                                               demo_resources):
    rehearsal = Rehearsal(make_app(tmp_path / "app"), "demo", participants=3, seed=1, conditions=(condition,))
    low, high = calibrate.bounds(parameter)

    def events(value: float) -> list[dict]:
        """The events, their times from their trial's start and without the lists' ids (fresh per list)."""
        frame = rehearsal.events(Human().with_values({parameter: value}))
        frame["client_t_ms"] -= frame.groupby(["participant", "trial"])["client_t_ms"].transform("min")
        rows = frame.to_dict("records")
        for row in rows:
            row["payload"] = {k: v for k, v in row["payload"].items() if k != "list_id"}
        return rows

    a = events(low)
    assert len(a) > 100 and a == events(high)


@pytest.mark.slow
def test_explain_says_which_condition_informs_which_parameter(tmp_path, demo_resources):
    rehearsal = Rehearsal(make_app(tmp_path / "app"), "demo", participants=3, seed=0, conditions=CONDITIONS)
    table = explain(rehearsal, step=1.0)
    rows = {r["parameter"]: r for r in table["parameters"]}
    assert list(rows) == free_parameters()
    for name, row in rows.items():
        assert set(row["effects"]) == {c.key for c in cells(CONDITIONS)}
        for key, effect in row["effects"].items():
            if key.split(".")[0] not in used_in(name):
                assert effect == 0.0, (name, key)  # a condition that does not use it cannot tell it
        assert set(row["informs"]) <= set(used_in(name))
    assert rows["scan_item_s"]["informs"]  # scanning time shows in the times of every list a person scans
    lines = explain_lines(table)
    assert lines[0].startswith("| Parameter | used in | none | basic | full |")
    assert any(line.startswith("| `suggestion_patience` | basic, full | 0 |") for line in lines)
    assert all(line.endswith(("no condition |", "` |")) for line in lines[2:])  # never a bare "none"


def test_the_engine_in_a_fingerprint_is_what_its_priors_hold_not_the_code_hash(rehearsal, tmp_path):
    """Priors retrained by changed engine code that learns the same numbers keep a calibration fresh; priors
    that learned other numbers make it stale."""
    from scenesuggest.npz import npz_bytes

    with np.load(rehearsal.study.priors) as z:
        arrays = {name: z[name] for name in z.files}
    meta = json.loads(arrays["meta"].tobytes())

    def saved(name, **changes):
        path = tmp_path / name
        path.write_bytes(npz_bytes({**arrays, **changes}))
        return path

    recoded = np.frombuffer(json.dumps({**meta, "code": "0" * 16}, sort_keys=True).encode(), dtype=np.uint8)
    same = calibrate.priors_content_sha256(rehearsal.study.priors)
    assert calibrate.priors_content_sha256(saved("recoded.npz", meta=recoded)) == same
    name = next(n for n in arrays if n != "meta" and arrays[n].size and arrays[n].dtype.kind == "f")
    assert calibrate.priors_content_sha256(saved("other.npz", **{name: arrays[name] + 1})) != same
    assert calibrate.priors_content_sha256(tmp_path / "missing.npz") is None


def test_drawn_cells_vary_as_another_study_of_the_papers_size_would():
    from simulation.calibrate import drawn_cells

    fold = cells(("none",))
    draws = [drawn_cells(fold, np.random.default_rng([0, k])) for k in range(400)]
    assert drawn_cells(fold, np.random.default_rng([0, 0])) == draws[0]  # seeded
    for i, cell in enumerate(fold):
        values = np.array([d[i].mean for d in draws])
        assert all(d[i].se == cell.se for d in draws[:5])  # weighed as the paper's
        if cell.kind == "share":
            assert values.min() >= 0 and values.max() <= 1
        else:
            assert abs(values.mean() - cell.mean) < 0.2 * cell.se and 0.8 < values.std() / cell.se < 1.2


def test_a_calibrations_uncertainty_is_refits_on_drawn_cells(rehearsal, tmp_path):
    from simulation.calibrate import add_draws, read_plausible

    document = fit(rehearsal, evaluations=2, draws=2, draw_evaluations=2, seed=3)
    assert len(document["draws"]) == 2 and document["draws_seed"] == 3
    assert document["draws"][0]["cells"] != document["draws"][1]["cells"]
    assert document["draws"][0]["evaluations"] == 2
    path = tmp_path / "drawn.json"
    write(document, path)
    sets = read_plausible(path, rehearsal.study)
    assert [h.values() for h in sets] == [document["parameters"], *(d["parameters"] for d in document["draws"])]
    more = add_draws(rehearsal, document, 3, evaluations=1, seed=3)  # only the missing one is made
    assert more["draws"][:2] == document["draws"] and len(more["draws"]) == 3
    with pytest.raises(SceneSuggestError, match="fitted on none cannot be refitted on none \\+ basic"):
        add_draws(Rehearsal(rehearsal.app, "demo", 2, 0, ("none", "basic")), document, 3)


def test_a_fit_writes_a_file_that_simulate_reads_and_refuses_when_stale(rehearsal, tmp_path):
    document = fit(rehearsal, evaluations=3)
    assert document["evaluations"] == 3 and math.isfinite(document["loss"]) and document["seed"] == 0
    assert document["free"] == free_parameters(("none",)) and document["on"] == ["none"]
    path = tmp_path / "calibration.json"
    write(document, path)
    human = read(path, rehearsal.study)
    assert human.values() == document["parameters"]
    other = json.loads(path.read_text())
    other["fingerprint"]["library_content_sha256"] = "0" * 64
    (tmp_path / "other.json").write_text(json.dumps(other))
    with pytest.raises(SceneSuggestError, match="another model library"):
        read(tmp_path / "other.json", rehearsal.study)
    other = json.loads(path.read_text())
    other["parameters"]["drag_error"] = float("nan")
    (tmp_path / "nan.json").write_text(json.dumps(other))
    with pytest.raises(SceneSuggestError, match="field 'parameters.drag_error': expected a finite number"):
        read(tmp_path / "nan.json")
    (tmp_path / "garbage.json").write_text("{not json")
    with pytest.raises(SceneSuggestError, match="not a calibration file"):
        read(tmp_path / "garbage.json")
    with pytest.raises(SceneSuggestError, match="no such calibration file"):
        read(tmp_path / "missing.json")
    with pytest.raises(SceneSuggestError, match=re.escape("field 'on': fitted on none, not on none + basic")):
        read(path, rehearsal.study, ("none", "basic"))
    assert calibrate.stale_keys(document, rehearsal.study, ("none", "full")) == ["conditions"]
    assert calibrate.stale_keys({**document, "version": 1}, rehearsal.study) == ["format"]
    for bad_on in (5, "none", ["none", "none"], ["full", "none"], ["none", "basic", "full"], ["\ud800"], None):
        (tmp_path / "on.json").write_text(json.dumps({**document, "on": bad_on}))
        with pytest.raises(SceneSuggestError, match="field 'on': not a fold of the paper's conditions"):
            read(tmp_path / "on.json")
        assert calibrate.stale_keys({**document, "on": bad_on}, rehearsal.study) == ["conditions"]
    corrected = {**document, "paper": {**document["paper"], "none.total_time": [205.0, 177.0, 241.0]}}
    assert calibrate.stale_keys(corrected, rehearsal.study) == ["paper's numbers"]
    assert calibrate.stale_keys(document, rehearsal.study) == []


@pytest.mark.slow
def test_cli_calibrate_then_simulate_with_it(tmp_path, demo_resources):
    env = {**os.environ, "DATABASE_URL": f"sqlite:///{tmp_path / 'db.sqlite3'}",
           "SCENESUGGEST_INSTANCE": str(tmp_path / "instance"), "SCENESUGGEST_STUDIES": str(DEMO_STUDY)}
    cli = [sys.executable, "-m", "scenesuggest.cli", "study"]
    out = tmp_path / "cal.json"
    run = subprocess.run([*cli, "calibrate", "-o", str(out), "--on", "full,none", "--participants", "2",
                          "--evaluations", "2", "--json"], capture_output=True, text=True, env=env, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    fitted = json.loads(run.stdout)
    assert fitted["evaluations"] == 2 and fitted["on"] == ["none", "full"] and "evaluation 2: loss" in run.stderr
    again = subprocess.run([*cli, "calibrate", "-o", str(out), "--on", "none,full", "--if-stale"],
                           capture_output=True, text=True, env=env, cwd=ROOT)
    assert again.returncode == 0 and "kept" in again.stdout, again.stderr
    sim = subprocess.run([*cli, "simulate", "--participants", "1", "--calibration", str(out), "--on", "none,full",
                          "--json"], capture_output=True, text=True, env=env, cwd=ROOT)
    assert sim.returncode == 0 and json.loads(sim.stdout)["completed"] == 1, sim.stderr
    (tmp_path / "on5.json").write_text(json.dumps({**json.loads(out.read_text()), "on": 5}))
    (tmp_path / "bad.toml").write_text("not = [toml")
    for args, message in [
            (["simulate", "--calibration", str(out), "--on", "none,basic"],
             "fitted on none + full, not on none + basic"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--on", "none", "--start", str(out)],
             "a fit on none cannot start from one fitted on none + full"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--on", "none,basic,full"], "predicts none"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--on", "oriented"], "no condition 'oriented'"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--on", "none\x01"], "no condition 'none\\x01'"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--draws", str(2 ** 31)], "--draws"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--workers", str(2 ** 31)], "--workers"),
            (["calibrate", "-o", str(tmp_path / "x.json"), "--start", str(tmp_path / "on5.json")],
             "field 'on': not a fold of the paper's conditions: 5"),
            (["power", "--calibration", str(out), "--against", str(tmp_path / "bad.toml")], "not valid TOML")]:
        refused = subprocess.run([*cli, *args], capture_output=True, text=True, env=env, cwd=ROOT)
        assert refused.returncode == 2 and message in refused.stderr, (args, refused.stderr)
        assert "Traceback" not in refused.stderr and not (tmp_path / "x.json").exists()
    (tmp_path / "other.json").write_text(out.read_text())
    other_fold = subprocess.run([*cli, "calibrate", "-o", str(tmp_path / "other.json"), "--on", "none",
                                 "--if-stale", "--participants", "2", "--evaluations", "1", "--json"],
                                capture_output=True, text=True, env=env, cwd=ROOT)
    assert other_fold.returncode == 0 and json.loads(other_fold.stdout)["on"] == ["none"], other_fold.stderr
    (tmp_path / "same.json").write_text(json.dumps({**json.loads(out.read_text()), "draws": 5}))  # malformed
    same_fold = subprocess.run([*cli, "calibrate", "-o", str(tmp_path / "same.json"), "--on", "none,full",
                                "--if-stale", "--participants", "2", "--evaluations", "1", "--json"],
                               capture_output=True, text=True, env=env, cwd=ROOT)
    assert same_fold.returncode == 0 and json.loads(same_fold.stdout)["evaluations"] == 1, same_fold.stderr
    table = subprocess.run([*cli, "calibrate", "--explain", "--participants", "2", "-o", str(tmp_path / "id.json")],
                           capture_output=True, text=True, env=env, cwd=ROOT)
    assert table.returncode == 0 and "| `suggestion_patience` | basic, full | 0 |" in table.stdout, table.stderr
    assert json.loads((tmp_path / "id.json").read_text())["explains"] is True
    power = subprocess.run([*cli, "power", "--calibration", str(out), "--participants", "4,6", "--studies", "10",
                            "--pilot", "3", "--sets", "2", "--json"], capture_output=True, text=True, env=env, cwd=ROOT)
    assert power.returncode == 0, power.stderr
    result = json.loads(power.stdout)
    assert result["parameter_sets"] == 2 and set(result["hypotheses"]) == {
        "H1 total time (none, basic, full)", "H2 rotation time (full vs basic)"}
    for h in result["hypotheses"].values():
        assert set(h["power"]) == {"4", "6"} and all(0 <= v["low"] <= v["best"] <= v["high"] <= 1
                                                      for v in h["power"].values())
    other = copy_demo_study(tmp_path / "other")  # the same study: its engines tell apart no better than chance
    engines = subprocess.run([*cli, "power", "--calibration", str(out), "--participants", "4", "--studies", "10",
                              "--pilot", "3", "--sets", "1", "--against", str(other), "--json"], capture_output=True,
                             text=True, env=env, cwd=ROOT)
    assert engines.returncode == 0, engines.stderr
    compared = json.loads(engines.stdout)
    assert compared["against"] == str(other) and set(compared["hypotheses"]) == {
        "E1 total time (full: the study's engine vs the other)", "E2 MRR (full: the study's engine vs the other)"}
    assert all(0 <= v["best"] <= 1 for h in compared["hypotheses"].values() for v in h["power"].values())
    renamed = other.read_text().replace('id = "demo"', 'id = "another"', 1)
    another = other.parent / "another.toml"
    another.write_text(renamed)
    refused = subprocess.run([*cli, "power", "--calibration", str(out), "--against", str(another)],
                             capture_output=True, text=True, env=env, cwd=ROOT)
    assert refused.returncode == 2 and "another study's file: its study is another, not demo" in refused.stderr
    (tmp_path / "bad.json").write_text(json.dumps({**json.loads(out.read_text()), "parameters": {"overlook": 2}}))
    bad = subprocess.run([*cli, "simulate", "--participants", "1", "--calibration", str(tmp_path / "bad.json")],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    assert bad.returncode == 2 and "field 'parameters.overlook': 2.0 is outside [0.0, 0.9]" in bad.stderr, bad.stderr
    assert "Traceback" not in bad.stderr


def test_two_runs_of_the_same_bots_pair_up_into_one_engine_comparison():
    import pandas as pd

    from simulation.power import OTHER, paired

    trials = pd.DataFrame({"participant": ["1", "1", "2", "2"], "position": [1, 2, 1, 2],
                           "scene": ["desk", "bed", "bed", "desk"], "condition": ["full", "none"] * 2,
                           "total_time": [100.0, 120.0, 90.0, 80.0]})
    picks = pd.DataFrame({"participant": ["1", "2"], "condition": ["full", "full"], "reciprocal_rank": [1.0, 0.5]})
    both_trials, both_picks = paired((trials, picks), (trials.assign(total_time=70.0), picks))
    assert sorted(both_trials["condition"].unique()) == ["full", f"full{OTHER}", "none", f"none{OTHER}"]
    assert len(both_trials) == 8 and len(both_picks) == 4
    assert both_trials.loc[both_trials["condition"] == f"full{OTHER}", "total_time"].tolist() == [70.0, 70.0]
    with pytest.raises(RuntimeError, match="do not pair up"):
        paired((trials, picks), (trials.assign(scene=["bed", "desk", "bed", "desk"]), picks))


def test_a_calibration_holds_for_the_same_library_built_from_another_checkout(tmp_path):
    """The library's fingerprint is what its models are, not where its corpus lay or which builder code made it:
    a copy built from another folder keeps a calibration fresh; a renamed model makes it stale."""
    index = {"format": "scenesuggest-library", "version": 1, "source": "stanford:/home/a/data", "code": "0" * 16,
             "models": [{"id": "m1", "category": "Mug", "name": "a mug", "tags": ["cup"],
                         "mesh": "/home/a/data/models/m1.obj"}]}
    path = tmp_path / "library.json"
    path.write_text(json.dumps(index))
    mine = calibrate.library_content_sha256(path)
    elsewhere = {**index, "source": "stanford:/srv/elsewhere/data", "code": "f" * 16,
                 "models": [{**index["models"][0], "mesh": "/srv/elsewhere/data/models/m1.obj"}]}
    path.write_text(json.dumps(elsewhere, indent=1))
    assert calibrate.library_content_sha256(path) == mine
    path.write_text(json.dumps({**index, "models": [{**index["models"][0], "mesh": "/home/a/data/models/m2.obj"}]}))
    assert calibrate.library_content_sha256(path) != mine  # another mesh
    path.write_text(json.dumps({**index, "models": [{**index["models"][0], "name": "a cup"}]}))
    assert calibrate.library_content_sha256(path) != mine
    assert calibrate.library_content_sha256(tmp_path / "missing.json") is None
