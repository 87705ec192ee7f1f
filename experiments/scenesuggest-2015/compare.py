"""The replication's results next to the paper's: writes ``results/comparison.md`` and ``results/comparison.json``.

Reads the report (``results/report/``, from ``scenesuggest analyze report``) and checks the engines on the
targets themselves (for each target object, a context query at its contact point in the target without it: the
rank of its category and how far the pose each interface suggests is from the target's — basic: the canonical
pose, full: the engine's orientation, and full with the paper's orientation rule — as the rotation error folded
by the model's rotational symmetry, :func:`scenesuggest.contract.pose_error.pose_error_deg`). The study's own engine
(the paper's) answers from the study's priors; beside it, every engine of ENGINES trained twice — without the targets'
source scenes (as the study's priors are) and on all 133 scenes, sources included (what the paper most likely
did) — so that the gap to the paper's participants can be split between the held-out protocol and the engine.
Those files are trained here once (about three minutes) and kept beside the prepared study (``engines.json``
says from which scenes and code).
The same calibrated bots also take the study with the learned engine serving ``basic`` and ``full`` (the study
file written by ``compare.py engines`` into the run directory, everything else unchanged): how far the
predictions move with an engine that ranks the targets better measures how much of the gap is the engine's.
Run by ``make replication``: ``compare.py engines`` first (trains the engine files, writes the variant study),
then the simulated runs and reports, then ``compare.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
RESULTS = HERE / "results"
PREPARED = ROOT / "var" / "experiments" / HERE.name
RUN = PREPARED / "run"
#: The study file of the variant whose suggestion conditions the learned engine serves, and its report.
LEARNED_STUDY, LEARNED_REPORT = RUN / "study-learned.toml", RUN / "report-learned"
sys.path.insert(0, str(HERE))

from targets import PERIODS  # noqa: E402

from analysis.bootstrap import bootstrap_by  # noqa: E402
from scenesuggest import engines  # noqa: E402
from scenesuggest.assets.symmetry import corpus_periods  # noqa: E402
from scenesuggest.atomic import write_atomically  # noqa: E402
from scenesuggest.contract.pose_error import pose_error_deg  # noqa: E402
from scenesuggest.engines.learned.engine import code_digest as learned_digest  # noqa: E402
from scenesuggest.engines.protocol import LoadContext  # noqa: E402
from scenesuggest.learning.priors import Priors, code_digest  # noqa: E402
from scenesuggest.library.index import load_index  # noqa: E402
from scenesuggest.scenes import scene_json  # noqa: E402
from scenesuggest.suggestion.suggest import ContextQuery, Engine  # noqa: E402
from simulation.calibrate import explain_lines  # noqa: E402
from simulation.paper_tables import CONDITIONS, RANK_TOLERANCE, TABLE1, TABLE2, cells  # noqa: E402

# Savva, Chang, Agrawala: SceneSuggest, Table 1's means and Table 2's rank-1 share (simulation/paper_tables.py),
# per measure a value per condition.
PAPER = {**{m: tuple(by[c][0] for c in CONDITIONS) for m, by in TABLE1.items()},
         "rank1_share": tuple(TABLE2["1"][c] for c in CONDITIONS)}
#: The calibrations side by side: the one fitted on `none` alone (the report in results/report/ is its run), and
#: the three that leave one condition out. Each file is calibration/<fold>.json; each run's report is in the run
#: directory (RUN / f"report-{fold}").
FOLDS = ("none", "none+basic", "none+full", "basic+full")
CALIBRATIONS = HERE / "calibration"
#: The paper's four findings, as the sign of differences of condition means: (name, measure, [(lower, higher)]).
DIRECTIONS = (("H1: suggestions are faster (total time none > basic > full)", "total_time",
               [("basic", "none"), ("full", "basic")]),
              ("H2: oriented suggestions save turning (rotation time full < basic)", "rotation_time",
               [("full", "basic")]),
              ("H3: suggestions replace searching (keyword queries basic, full < none)", "n_text_queries",
               [("basic", "none"), ("full", "none")]),
              ("MRR: suggestions rank the wanted model higher (MRR none < basic, full)", "mrr",
               [("none", "basic"), ("none", "full")]))
LABELS = {
    "total_time": "Total time (s)", "rotation_time": "Rotation time (s)", "translation_time": "Translation time (s)",
    "n_text_queries": "Keyword queries", "mrr": "MRR", "rank1_share": "Rank-1 picks",
}
TURN_TOLERANCE_DEG = 15.0
#: The engines compared on the targets, and the scenes each set of their files is trained on.
ENGINES = ("paper", "learned", "frequency")
ROW_SETS = {"held_out": "trained without the targets' source scenes", "all": "trained on all 133 scenes"}


def simulated(report: Path) -> dict[str, tuple[dict, ...]]:
    """Per measure, per condition: mean and 95% bootstrap interval from the report's tables and measures."""
    results = json.loads((report / "results.json").read_text())
    trials = pd.read_csv(report / "measures" / "trials.csv")
    trials = trials[trials["kind"] == "trial"]
    seed, resamples = results.get("seed", 0), results.get("resamples", 1000)
    out = {}
    t1 = {row["condition"]: row for row in results["table1"]}
    for key, column in (("total_time", "total_time"), ("rotation_time", "rotation_time"),
                        ("translation_time", "translation_time"), ("mrr", "reciprocal_rank")):
        out[key] = tuple({"mean": t1[c][f"{column}_mean"], "low": t1[c][f"{column}_low"],
                          "high": t1[c][f"{column}_high"]} for c in CONDITIONS)
    queries = bootstrap_by(trials, "n_text_queries", "condition", list(CONDITIONS), resamples=resamples, seed=seed)
    out["n_text_queries"] = tuple({"mean": queries[c].mean, "low": queries[c].low, "high": queries[c].high}
                                  for c in CONDITIONS)
    picks = pd.read_csv(report / "measures" / "picks.csv")
    picks = picks[picks["final"].astype(bool) & picks["rank"].notna()]
    for label, hit in (("1", picks["rank"] == 1), ("2", picks["rank"] == 2), ("3", picks["rank"] == 3),
                       ("4+", picks["rank"] >= 4)):
        shares = bootstrap_by(picks.assign(hit=hit.astype(float)), "hit", "condition", list(CONDITIONS),
                              unit="trial", resamples=resamples, seed=seed)
        out[f"rank_{label}"] = tuple({"mean": shares[c].mean, "low": shares[c].low, "high": shares[c].high}
                                     for c in CONDITIONS)
    out["rank1_share"] = out["rank_1"]
    chosen = lambda v: {"random": v["selection"]["kept"], "intercepts_only": v["selection"]["intercepts_only"]}  # noqa
    out["_lrt"] = {k: v["lrt"] | (chosen(v) if v.get("selection") else {})
                   for k, v in results["tests"].items() if v and "lrt" in v}
    out["_n"] = {"participants": results["participants"], "trials": results["trials"], "picks": results["picks"]}
    return out


def _targets(prepared: Path):
    """(scene id, object, its context query) for every supported object of every target, in the study's order."""
    for scene_id in [s for period in PERIODS for s in period]:
        scene = scene_json.load(prepared / "scenes" / f"{scene_id}.json")
        for o in scene:
            if o.parent is not None:
                yield scene_id, o, ContextQuery(scene.without(o.id), o.parent, o.contact_point, o.contact_normal,
                                                scene.scene_type)


def engine_on_targets(prepared: Path) -> list[dict]:
    """For every object of every target: the study engine's rank of its category and the folded rotation error
    (degrees) of the pose each interface suggests for it."""
    engine = Engine(Priors.load(prepared / "priors.npz"))
    by_mode = {"basic": (engine, "basic"), "full": (engine, "full"),
               "paper": (engine.with_options(orientation="paper"), "full")}
    library = load_index(prepared / "library")
    periods = corpus_periods(library.values(), base=prepared / "library")
    rows = []
    for scene_id, o, query in _targets(prepared):
        period, _ = periods.of(o.model_id, o.category, (o.size[0], o.size[2]))
        row = {"scene": scene_id, "object": o.id, "category": o.category, "period_deg": period}
        for name, (by, mode) in by_mode.items():
            found = [s for s in by.suggest(query, mode=mode) if s.category == o.category]
            if name == "full":
                row["rank"] = found[0].rank if found else None
            if found:
                row[f"turn_{name}_deg"] = round(pose_error_deg(found[0].placement, o.transform, period), 1)
        rows.append(row)
    return rows


def trained_engines(prepared: Path, names=ENGINES, log=print) -> dict[str, dict]:
    """Per row set (ROW_SETS), per engine of ``names``: the engine trained on that set's scenes. Files are kept in
    ``prepared`` (``priors.npz`` is the study's own, from prepare.py) and trained again only when the corpus, the
    held-out scenes or the engine code changed (``engines.json`` records what each was trained from)."""
    from scenesuggest.corpora import load_corpus

    manifest = json.loads((prepared / "manifest.json").read_text())
    record_path = prepared / "engines.json"
    record = json.loads(record_path.read_text()) if record_path.is_file() else {}
    corpus = None

    def ensure(file: Path, kind, config, row_set: str, code: str) -> None:
        nonlocal corpus
        key = {"corpus": manifest["corpus"], "held_out": manifest["held_out"], "row_set": row_set, "code": code}
        if file.is_file() and record.get(file.name) == key:
            return
        corpus = corpus or load_corpus(f"stanford:{manifest['corpus']}")
        scenes = [s for s in corpus.scenes if row_set == "all" or s.id not in set(manifest["held_out"])]
        log(f"training the {kind.name} engine on {len(scenes)} scenes → {file} …")
        kind.train(config, scenes, corpus.taxonomy, file, periods=corpus_periods(corpus.models.values()))
        record[file.name] = key
        write_atomically(record_path, (json.dumps(record, indent=1) + "\n").encode())

    out: dict[str, dict] = {}
    for row_set in ROW_SETS:
        priors_file = prepared / ("priors.npz" if row_set == "held_out" else "priors-all.npz")
        if row_set != "held_out":
            paper = engines.configure({"name": "paper"})
            ensure(priors_file, paper.kind, paper.config, row_set, code_digest())
        priors = Priors.load(priors_file)
        out[row_set] = {}
        for name in names:
            spec = engines.configure({"name": name})
            if hasattr(spec.kind, "from_priors"):
                out[row_set][name] = spec.kind.from_priors(spec.config, priors)
                continue
            file = prepared / (f"{name}.npz" if row_set == "held_out" else f"{name}-all.npz")
            ensure(file, spec.kind, spec.config, row_set, learned_digest())
            out[row_set][name] = engines.load(engines.configure({"name": name, "file": str(file)}),
                                              LoadContext(priors_file))
    return out


def engines_on_targets(prepared: Path, trained: dict[str, dict]) -> list[dict]:
    """For every object of every target, per row set and engine: the rank of its category (among every category
    the engine knows) and the folded rotation error (degrees) of its full-mode pose."""
    library = load_index(prepared / "library")
    periods = corpus_periods(library.values(), base=prepared / "library")
    rows = []
    for scene_id, o, query in _targets(prepared):
        period, _ = periods.of(o.model_id, o.category, (o.size[0], o.size[2]))
        row = {"scene": scene_id, "object": o.id, "category": o.category}
        for row_set, by_name in trained.items():
            for name, engine in by_name.items():
                ranked = engine.suggest(query, "full")
                found = [s for s in ranked if s.category == o.category]
                row[f"{row_set}.{name}.rank"] = found[0].rank if found else None
                if found:
                    row[f"{row_set}.{name}.turn_deg"] = round(pose_error_deg(found[0].placement, o.transform,
                                                                             period), 1)
        rows.append(row)
    return rows


def engine_lines(rows: list[dict], trained: dict[str, dict]) -> list[str]:
    """The per-engine table of the targets: MRR, rank-1 count and worst rank per scene, for each row set."""
    frame = pd.DataFrame(rows)
    lines = ["", "### Every engine on the targets", "",
             "The same queries asked of every engine: trained without the targets' source scenes (as the study's "
             "priors are), and on all 133 scenes, the sources included (what the paper most likely did). MRR, the "
             "objects whose category is ranked first, the worst rank, and the objects more than "
             f"{TURN_TOLERANCE_DEG:.0f}° from their target pose in full mode.", ""]
    for row_set, by_name in trained.items():
        names = list(by_name)
        lines += [f"{ROW_SETS[row_set].capitalize()}:", "",
                  "| Scene | Objects | " + " | ".join(f"{n} MRR | rank 1 | worst | turn" for n in names) + " |",
                  "|---|---:|" + "---:|---:|---:|---:|" * len(names)]
        for scene_id, g in [*frame.groupby("scene", sort=False), ("all", frame)]:
            cells = []
            for n in names:
                ranks = g[f"{row_set}.{n}.rank"]
                rr = np.where(ranks.notna(), 1.0 / ranks.fillna(np.inf), 0.0)
                worst = "–" if ranks.isna().any() else f"{int(ranks.max())}"
                turns = int((g[f"{row_set}.{n}.turn_deg"].fillna(180.0) > TURN_TOLERANCE_DEG).sum()) \
                    if f"{row_set}.{n}.turn_deg" in g else len(g)
                cells.append(f"{rr.mean():.3f} | {int((ranks == 1).sum())} | {worst} | {turns}")
            lines.append(f"| {scene_id} | {len(g)} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def _fmt(key: str, v: float | None) -> str:
    if v is None:
        return "–"
    if key == "rank1_share":
        return f"{100 * v:.1f}%"
    if key == "mrr":
        return f"{v:.3f}"
    return f"{v:.1f}"


def _direction(values) -> str:
    """The order of basic and full relative to none, and of full relative to basic: − lower, + higher."""
    none, basic, full = values
    return " ".join("−" if b < a else "+" if b > a else "=" for a, b in ((none, basic), (none, full), (basic, full)))


def _cell(key: str, mean, low=None, high=None) -> str:
    return _fmt(key, mean) + (f" [{_fmt(key, low)}, {_fmt(key, high)}]" if low is not None else "")


def predictions(sim: dict, on: tuple[str, ...] = ("none",)) -> list[dict]:
    """Every cell of Table 1 and Table 2, paper beside simulated: the conditions ``on`` are what the simulator was
    calibrated on; the others are predictions, matched when a Table 1 mean falls inside the paper's 95% interval
    and a Table 2 share within RANK_TOLERANCE of the paper's."""
    rows = []
    for cell in cells(CONDITIONS, spreads=False):
        ours = sim[cell.measure][CONDITIONS.index(cell.condition)]
        rows.append({"table": cell.table, "measure": cell.measure, "condition": cell.condition, "paper": cell.mean,
                     "paper_low": cell.low, "paper_high": cell.high,
                     **{f"simulated{k}": ours[v] for k, v in (("", "mean"), ("_low", "low"), ("_high", "high"))},
                     "role": "calibrated" if cell.condition in on else "predicted",
                     "matched": bool(cell.matched(ours["mean"]))})
    return rows


def directions(sim: dict) -> list[dict]:
    """The paper's four findings (DIRECTIONS) in the simulated means: each reproduced when every difference has
    the paper's sign."""
    out = []
    for name, key, pairs in DIRECTIONS:
        means = {c: sim[key][CONDITIONS.index(c)]["mean"] for c in CONDITIONS}
        out.append({"finding": name, "reproduced": all(means[lo] < means[hi] for lo, hi in pairs),
                    "means": means})
    return out


def fold_summary(fold: str, sim: dict) -> dict:
    """One calibration's run: its cells (calibrated and predicted), how many of each matched, its findings, and its
    calibration file's loss and cost."""
    on = tuple(fold.split("+"))
    rows = predictions(sim, on)
    calibration = json.loads((CALIBRATIONS / f"{fold}.json").read_text())
    if calibration.get("on") != list(on):
        raise SystemExit(f"{CALIBRATIONS / f'{fold}.json'}: fitted on {calibration.get('on')}, not on {list(on)}")
    count = {role: [sum(r["matched"] for r in rows if r["role"] == role), sum(r["role"] == role for r in rows)]
             for role in ("calibrated", "predicted")}
    return {"fold": fold, "on": list(on), "cells": rows, "matched": count, "directions": directions(sim),
            "participants": sim["_n"]["participants"]["completed"],
            "calibration": {k: calibration[k] for k in ("loss", "loss_without_prior", "evaluations", "seconds",
                                                          "converged", "free", "parameters", "measured")}}


def fold_lines(folds: list[dict], identifiability: dict | None) -> list[str]:
    """The calibrations side by side: every cell under each, calibrated cells marked, predicted ones matched or
    not; then each fold's counts and findings, and what each condition can tell."""
    names = [f["fold"] for f in folds]
    lines = ["", "## Leave one condition out: what each condition predicts of the others", "",
             "Four calibrations of the same bots: on `none` alone (the run above), and on two conditions each, the "
             "third predicted. A fold never reads the held-out condition's numbers (`simulation/paper_tables.py` "
             "hands a fit its own conditions' cells only; a test changes the others and finds the fit unchanged). "
             f"Each run: {', '.join(str(f['participants']) for f in folds)} bots that completed the study (in the "
             "columns' order). A cell the fold was fitted on is marked *fit*; a predicted cell ✓ when a "
             "Table 1 mean is inside the paper's interval or a Table 2 share within "
             f"{100 * RANK_TOLERANCE:.0f} points, else ✗.", "",
             f"| Table | Measure | Condition | Paper | {' | '.join(names)} |",
             f"|---:|---|---|---:|{'---:|' * len(names)}"]
    for i, first in enumerate(folds[0]["cells"]):
        key = "rank1_share" if first["table"] == 2 else first["measure"]
        label = LABELS[first["measure"]] if first["table"] == 1 else f"Rank {first['measure'].split('_')[1]} picks"
        row = []
        for f in folds:
            r = f["cells"][i]
            mark = "*fit*" if r["role"] == "calibrated" else "✓" if r["matched"] else "✗"
            row.append(f"{_cell(key, r['simulated'], r['simulated_low'], r['simulated_high'])} {mark}")
        lines.append(f"| {first['table']} | {label} | {first['condition']} | "
                     f"{_cell(key, first['paper'], first['paper_low'], first['paper_high'])} | {' | '.join(row)} |")
    lines += ["", "| Calibration | loss (without prior) | evaluations, seconds | fitted cells matched | "
                  "predicted cells matched | findings reproduced |", "|---|---:|---:|---:|---:|---|"]
    for f in folds:
        c, (fm, fn), (pm, pn) = f["calibration"], f["matched"]["calibrated"], f["matched"]["predicted"]
        found = ", ".join(d["finding"].split(":")[0] for d in f["directions"] if d["reproduced"]) or "none"
        lines.append(f"| {f['fold']} | {c['loss']:.1f} ({c['loss_without_prior']:.1f}) | {c['evaluations']}, "
                     f"{c['seconds']:.0f} s | {fm} of {fn} | {pm} of {pn} | {found} |")
    lines += ["", "Findings: " + "; ".join(d["finding"] for d in folds[0]["directions"]) + "."]
    if identifiability:
        lines += ["", "### What each condition can tell (`scenesuggest study calibrate --explain`)", "",
                  "How far each cell of a condition moves when a parameter moves by one logit about the `none` "
                  "fit (the largest over the condition's cells, in the cell's standard errors, and which cell), "
                  f"{identifiability['participants']} bots, common random numbers. A parameter is informed by a "
                  f"condition when it moves one of its cells by {identifiability['informs_se']} standard errors "
                  "or more; a condition whose trials do not use it cannot inform it at all (0).", ""]
        lines += explain_lines(identifiability)
    return lines


def _prediction_row(r: dict, with_role: bool) -> str:
    """One row of a predictions table: the paper's cell and the simulated one, with their intervals."""
    key = "rank1_share" if r["table"] == 2 else r["measure"]
    label = LABELS[r["measure"]] if r["table"] == 1 else f"Rank {r['measure'].split('_')[1]} picks"
    role = f" {r['role']} |" if with_role else ""
    return (f"| {r['table']} | {label} | {r['condition']} |{role} "
            f"{_cell(key, r['paper'], r['paper_low'], r['paper_high'])} | "
            f"{_cell(key, r['simulated'], r['simulated_low'], r['simulated_high'])} | "
            f"{'yes' if r['matched'] else 'no'} |")


def prediction_lines(rows: list[dict]) -> list[str]:
    lines = ["", "## Every cell of Table 1 and Table 2: calibrated on `none`, predicted for `basic` and `full`", "",
             "The simulated participants' free parameters were fitted to the paper's `none` row only "
             "(`calibration/none.json`, `scenesuggest study calibrate`); `basic` and `full` are predictions. A Table 1 "
             "prediction matches when its mean is inside the paper's 95% interval; a Table 2 share when it is within "
             f"{100 * RANK_TOLERANCE:.0f} points of the paper's (the paper gives no interval).", "",
             "| Table | Measure | Condition | Role | Paper | Simulated [95% interval] | Matched |",
             "|---:|---|---|---|---:|---:|:---:|"]
    lines += [_prediction_row(r, with_role=True) for r in rows]
    predicted = [r for r in rows if r["role"] == "predicted"]
    lines += ["", f"Predictions matched: {sum(r['matched'] for r in predicted)} of {len(predicted)}.", ""]
    return lines


def model_choices(report: Path, prepared: Path) -> dict[str, dict[str, int]]:
    """Per condition, how many final picks chose the target object's own model and how many another model of its
    category (a participant may choose either)."""
    picks = pd.read_csv(report / "measures" / "picks.csv")
    picks = picks[picks["final"].astype(bool)]
    wanted = {}
    for scene_id in {s for period in PERIODS for s in period}:
        for o in scene_json.load(prepared / "scenes" / f"{scene_id}.json"):
            wanted.setdefault((scene_id, o.category), set()).add(o.model_id)
    out = {}
    for c in CONDITIONS:
        own = picks[picks["condition"] == c]
        same = [m in wanted.get((sc, cat), ()) for m, sc, cat in zip(own["model"], own["scene"], own["category"],
                                                                      strict=True)]
        known = [(sc, cat) in wanted for sc, cat in zip(own["scene"], own["category"], strict=True)]
        out[c] = {"target_model": int(sum(same)),
                  "other_model_of_category": int(sum(k and not s for k, s in zip(known, same, strict=True))),
                  "other_category": int(sum(not k for k in known))}
    return out


def write(sim: dict, engine_rows: list[dict], out: Path, per_engine: list[dict] | None = None,
          trained: dict[str, dict] | None = None, choices: dict | None = None, variant: dict | None = None,
          folds: list[dict] | None = None, identifiability: dict | None = None) -> None:
    lines = ["# The replication next to the paper (simulated participants)", "",
             "Generated by `make replication` (experiments/scenesuggest-2015/compare.py). **Simulated participants**: "
             f"{sim['_n']['participants']['completed']} bots (keystroke-level model with people's behaviour, "
             "calibrated on the paper's `none` condition), "
             f"{sim['_n']['trials']['completed']} trials, {sim['_n']['picks']} picks — not people.", "",
             "Means per trial (MRR and rank-1 share: per pick) with 95% bootstrap intervals. Direction: the sign of "
             "basic − none, full − none and full − basic.", "",
             "| Measure | Paper none | basic | full | Simulated none | basic | full | Direction paper | simulated |",
             "|---|---:|---:|---:|---:|---:|---:|:---:|:---:|"]
    for key, paper in PAPER.items():
        ours = sim[key]
        cells = [f"{_fmt(key, s['mean'])}" + (f" [{_fmt(key, s['low'])}, {_fmt(key, s['high'])}]"
                                                if s["low"] is not None else "") for s in ours]
        lines.append(f"| {LABELS[key]} | " + " | ".join(_fmt(key, p) for p in paper) + " | " + " | ".join(cells)
                     + f" | {_direction(paper)} | {_direction([s['mean'] for s in ours])} |")
    lines += ["", "Relative to `none` (ratio of means):", "",
              "| Measure | Paper basic/none | full/none | Simulated basic/none | full/none |",
              "|---|---:|---:|---:|---:|"]
    for key, paper in PAPER.items():
        ours = [s["mean"] for s in sim[key]]
        lines.append(f"| {LABELS[key]} | {paper[1] / paper[0]:.2f} | {paper[2] / paper[0]:.2f} | "
                     f"{ours[1] / ours[0]:.2f} | {ours[2] / ours[0]:.2f} |")
    lines += ["", "Likelihood-ratio tests of condition (simulated): under the random effects the report chose for each "
              "measure (its table “Random effects chosen” has every step), and with random intercepts alone:", "",
              "| Measure | Random effects | χ² | df | p | Intercepts only: χ² | p |",
              "|---|---|---:|---:|---:|---:|---:|"]
    p_text = lambda p: "< .001" if p < 0.001 else f"{p:.3f}"  # noqa: E731
    for key, lrt in sim["_lrt"].items():
        alone = lrt.get("intercepts_only") or lrt
        lines.append(f"| {key} | {lrt.get('random', 'intercepts only')} | {lrt['chi2']:.2f} | {lrt['df']} | "
                     f"{p_text(lrt['p'])} | {alone['chi2']:.2f} | {p_text(alone['p'])} |")
    rows = predictions(sim)
    lines += prediction_lines(rows)
    if folds:
        lines += fold_lines(folds, identifiability)
        lines.append("")
    if choices:
        lines += ["Which model was chosen (final picks): the target object's own, another of its category, or a "
                  "model of another category.", "", "| Condition | Target's model | Another of its category | "
                  "Another category |", "|---|---:|---:|---:|"]
        lines += [f"| {c} | {v['target_model']} | {v['other_model_of_category']} | {v['other_category']} |"
                  for c, v in choices.items()]
    frame = pd.DataFrame(engine_rows)
    ranked = frame["rank"].notna()
    rr = np.where(ranked, 1.0 / frame["rank"].fillna(np.inf), 0.0)
    lines += ["", "## The engine on the targets", "",
              "For each target object, a context query at its contact point in the target scene without it (what a "
              "participant's click asks): the rank of the object's category, and how many objects each interface "
              "leaves more than "
              f"{TURN_TOLERANCE_DEG:.0f}° from their target pose (the rotation error folded by the model's "
              "rotational symmetry: a vase never needs a turn, a rectangular table at most 90°) — basic: the "
              "canonical pose; full: the engine's orientation; paper: full with the paper's orientation rule.", "",
              "| Scene | Objects | MRR | Rank 1 | Need a turn in basic | in full | in full, paper's rule |",
              "|---|---:|---:|---:|---:|---:|---:|"]

    def turns(g, name):  # a category the interface never suggests counts as needing a turn (it must be searched for)
        return int((g[f"turn_{name}_deg"].fillna(180.0) > TURN_TOLERANCE_DEG).sum())

    for scene_id, g in [*frame.groupby("scene", sort=False), ("all", frame)]:
        g_rr = rr[g.index]
        lines.append(f"| {scene_id} | {len(g)} | {g_rr.mean():.3f} | {(g['rank'] == 1).sum()} | "
                     f"{turns(g, 'basic')} | {turns(g, 'full')} | {turns(g, 'paper')} |")
    if per_engine:
        lines += engine_lines(per_engine, trained)
    if variant:
        lines += variant_lines(variant)
    lines += ["", "Per object: `comparison.json`.", ""]
    out.mkdir(parents=True, exist_ok=True)
    (out / "comparison.md").write_text("\n".join(lines))
    doc = {"paper": PAPER, "simulated": {k: v for k, v in sim.items() if not k.startswith("_")},
           "lr_tests": sim["_lrt"], "n": sim["_n"], "engine_on_targets": engine_rows,
           "engines_on_targets": per_engine or [], "predictions": rows, "model_choices": choices or {},
           "learned_engine_predictions": [r for r in predictions(variant) if r["role"] == "predicted"]
           if variant else [], "folds": folds or [], "identifiability": identifiability}
    (out / "comparison.json").write_text(json.dumps(doc, indent=1, default=float) + "\n")


def learned_variant(study_file: Path, learned: Path) -> str:
    """The text of study file ``study_file`` with its ``basic`` and ``full`` conditions served by the learned
    engine trained in ``learned`` (paths made absolute, so that the text may live anywhere)."""
    text = study_file.read_text()
    lines = []
    for line in text.splitlines():
        if line.startswith(("priors = ", "library = ", "target = ")):
            key, value = line.split(" = ", 1)
            line = f"{key} = {json.dumps(str((study_file.parent / json.loads(value)).resolve()))}"
        lines.append(line)
        if line in ('id = "basic"', 'id = "full"'):
            lines.append(f'engine = {{ name = "learned", file = {json.dumps(str(learned))} }}')
    variant = "\n".join(lines) + "\n"
    if variant.count('name = "learned"') != 2:
        raise SystemExit(f"{study_file}: expected conditions with ids basic and full")
    return variant


def variant_lines(sim: dict) -> list[str]:
    """The predicted cells again, for the study with the learned engine serving the suggestions."""
    rows = [r for r in predictions(sim) if r["role"] == "predicted"]
    lines = ["", "## The same bots with the learned engine serving `basic` and `full`", "",
             "The calibrated bots of the run above take the study again, its suggestion conditions served by the "
             "learned engine (trained without the targets' sources, as the study's priors are); nothing else "
             "changes. What moves is what the engine's ranking decides.", "",
             "| Table | Measure | Condition | Paper | Simulated [95% interval] | Matched |",
             "|---:|---|---|---:|---:|:---:|"]
    lines += [_prediction_row(r, with_role=False) for r in rows]
    lines += ["", f"Predictions matched with the learned engine: {sum(r['matched'] for r in rows)} of {len(rows)}.",
              ""]
    return lines


def main(argv: list[str]) -> int:
    trained = trained_engines(PREPARED)
    if argv[:1] == ["engines"]:
        RUN.mkdir(parents=True, exist_ok=True)
        write_atomically(LEARNED_STUDY, learned_variant(HERE / "study.toml", PREPARED / "learned.npz").encode())
        print(f"wrote {LEARNED_STUDY}")
        return 0
    variant = simulated(LEARNED_REPORT) if (LEARNED_REPORT / "results.json").is_file() else None
    folds = [fold_summary(fold, simulated(RESULTS / "report" if fold == "none" else RUN / f"report-{fold}"))
             for fold in FOLDS if fold == "none" or (RUN / f"report-{fold}" / "results.json").is_file()]
    explained = CALIBRATIONS / "identifiability.json"
    identifiability = json.loads(explained.read_text()) if explained.is_file() else None
    write(simulated(RESULTS / "report"), engine_on_targets(PREPARED), RESULTS,
          engines_on_targets(PREPARED, trained), trained, model_choices(RESULTS / "report", PREPARED), variant,
          folds, identifiability)
    print(f"wrote {RESULTS / 'comparison.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
