"""Simulated participants that behave like people, and their calibration on the paper's ``none`` condition only."""

from __future__ import annotations

import ast
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
from demostudy import DEMO_STUDY, make_app
from support import ROOT

from scenesuggest.errors import SceneSuggestError
from simulation import calibrate
from simulation.calibrate import PAPER_NONE, Rehearsal, fit, loss, measure, read, write
from simulation.human import Human, describe, free_parameters
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
    assert set(measured) >= set(PAPER_NONE) and all(math.isfinite(v) for v in measured.values())
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
              human=Human(category_words=0.0))
    bot.library = {"m": {"id": "m", "name": "Tall Lamp 3000", "tags": ["light"],
                         "category_path": ["Lighting", "FloorLamp"]}}
    from simulation.actions import BotTrial

    trial = BotTrial(bot, {"token": "", "page_id": "p", "vocabulary": 2, "batch": 200,
                        "trial": {"index": 0, "scene": "desk", "condition": "none", "kind": "trial"}})
    texts = trial.search_texts({"model_id": "m", "category": "FloorLamp"})
    assert texts[0] in ("tall", "tall lamp") and "floor lamp" in texts and "lighting" in texts


def test_the_loss_is_zero_at_the_paper_and_grows_away_from_it():
    at_paper = {**{k: v[0] for k, v in PAPER_NONE.items()},
                **{f"rank_{k}": v for k, v in calibrate.PAPER_NONE_RANKS.items()}}
    assert loss(at_paper) == 0
    assert loss({**at_paper, "total_time": 241.0}) == pytest.approx(1.96 ** 2 * 4 * 37 ** 2 / 64 ** 2)
    assert loss({**at_paper, "mrr": float("nan")}) == 1e9


def test_the_calibration_never_reads_the_other_conditions():
    """The fit may only see the paper's `none` numbers: its source names no other condition, holds none of their
    Table 1 or Table 2 numbers, and imports nothing that does (the replication's comparison holds them)."""
    source = Path(calibrate.__file__).read_text()
    tree = ast.parse(source)
    assert not {"basic", "full"} & {w.strip("`'\".,:;()").lower() for w in source.split()}
    numbers = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, float)}
    others = {170.0, 130.0, 267.0, 139.0, 118.0, 168.0, 22.4, 19.5, 26.5, 17.2, 14.3, 21.1, 38.5, 31.0, 50.1,
              39.8, 30.1, 62.5, 3.3, 2.3, 4.9, 2.5, 1.6, 3.9, 0.785, 0.765, 0.805, 0.769, 0.747, 0.791, 0.687,
              0.675, 0.111, 0.0984, 0.0428, 0.0487, 0.159, 0.178}
    assert not numbers & others
    imported = {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)} | {
        a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not any("compare" in m or "experiments" in m or "analysis.report" in m for m in imported)


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


def test_a_fit_writes_a_file_that_simulate_reads_and_refuses_when_stale(rehearsal, tmp_path):
    document = fit(rehearsal, evaluations=3)
    assert document["evaluations"] == 3 and math.isfinite(document["loss"]) and document["seed"] == 0
    assert set(document["free"]) == set(free_parameters())
    path = tmp_path / "calibration.json"
    write(document, path)
    human = read(path, rehearsal.study)
    assert human.values() == document["parameters"]
    other = json.loads(path.read_text())
    other["fingerprint"]["library_sha256"] = "0" * 64
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


@pytest.mark.slow
def test_cli_calibrate_then_simulate_with_it(tmp_path, demo_resources):
    env = {**os.environ, "DATABASE_URL": f"sqlite:///{tmp_path / 'db.sqlite3'}",
           "SCENESUGGEST_INSTANCE": str(tmp_path / "instance"), "SCENESUGGEST_STUDIES": str(DEMO_STUDY)}
    cli = [sys.executable, "-m", "scenesuggest.cli", "study"]
    out = tmp_path / "cal.json"
    run = subprocess.run([*cli, "calibrate", "-o", str(out), "--participants", "2", "--evaluations", "2",
                          "--json"], capture_output=True, text=True, env=env, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["evaluations"] == 2 and "evaluation 2: loss" in run.stderr
    again = subprocess.run([*cli, "calibrate", "-o", str(out), "--if-stale"], capture_output=True, text=True,
                           env=env, cwd=ROOT)
    assert again.returncode == 0 and "kept" in again.stdout, again.stderr
    sim = subprocess.run([*cli, "simulate", "--participants", "1", "--calibration", str(out), "--json"],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    assert sim.returncode == 0 and json.loads(sim.stdout)["completed"] == 1, sim.stderr
    power = subprocess.run([*cli, "power", "--calibration", str(out), "--participants", "4,6", "--studies", "10",
                            "--pilot", "3", "--sets", "2", "--json"], capture_output=True, text=True, env=env, cwd=ROOT)
    assert power.returncode == 0, power.stderr
    result = json.loads(power.stdout)
    assert result["parameter_sets"] == 2 and set(result["hypotheses"]) == {
        "H1 total time (none, basic, full)", "H2 rotation time (full vs basic)"}
    for h in result["hypotheses"].values():
        assert set(h["power"]) == {"4", "6"} and all(0 <= v["low"] <= v["best"] <= v["high"] <= 1
                                                      for v in h["power"].values())
    (tmp_path / "bad.json").write_text(json.dumps({**json.loads(out.read_text()), "parameters": {"overlook": 2}}))
    bad = subprocess.run([*cli, "simulate", "--participants", "1", "--calibration", str(tmp_path / "bad.json")],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    assert bad.returncode == 2 and "field 'parameters.overlook': 2.0 is outside [0.0, 0.9]" in bad.stderr, bad.stderr
    assert "Traceback" not in bad.stderr
