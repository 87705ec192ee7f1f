"""The human tables of :func:`scenesuggest.evaluation.evaluate.evaluate`'s result: ranking against the baselines,
orientation (with the paper's rule, the canonical pose, the frame classifier's choice and the frame oracle where
measured), the engines side by side with the paired intervals of their MRR differences, and per category; and of
:func:`scenesuggest.evaluation.transfer.evaluate_transfer`'s (:func:`format_transfer`)."""

from __future__ import annotations

import math

from .evaluate import BASELINES, POSES


def _ranking_rows(block: dict) -> list[str]:
    rows = [("basic", block["modes"]["basic"]), ("full", block["modes"]["full"])]
    rows += [(f"- {b}", block["baselines"][b]) for b in BASELINES]
    return [f"{name:<14}{m['mrr']:>8.3f}{m['top1']:>8.3f}{m['top5']:>8.3f}" for name, m in rows]


def _orientation_rows(full: dict) -> list[str]:
    lines = [f"{'orientation':<14}{'≤15°':>8}{'≤45°':>8}{'folded ≤15°':>13}{'≤45°':>8}{'median':>9}"]
    rows = [("full", full), ("paper's rule", full.get("paper")), ("frame choice", full.get("frames")),
            ("canonical", full["canonical"])]
    for name, m in [(n, m) for n, m in rows if m is not None]:
        lines.append(f"{name:<14}{100 * m['orient_within_15']:>7.1f}%{100 * m['orient_within_45']:>7.1f}%"
                     f"{100 * m['orient_folded_within_15']:>12.1f}%{100 * m['orient_folded_within_45']:>7.1f}%"
                     f"{m['orient_median_deg']:>8.1f}°")
    if "frame_oracle" in full:
        m = full["frame_oracle"]
        lines.append(f"{'frame oracle':<14}{'':>8}{'':>8}{100 * m['orient_folded_within_15']:>12.1f}%"
                     f"{100 * m['orient_folded_within_45']:>7.1f}%{m['orient_median_deg']:>8.1f}°")
    return lines


def _engine_rows(result: dict) -> list[str]:
    """The engines side by side: ranking, orientation, query time and the paired difference from the first."""
    lines = [f"{'engine':<12}{'MRR':>7}{'top-1':>7}{'top-5':>7}{'folded ≤45°':>13}{'canonical':>11}{'frames':>8}"
             f"{'oracle':>8}"
             f"{'p50 ms':>8}{'p95 ms':>8}  MRR − {result['engine']} [95% CI]"]
    for name, block in result["engines"].items():
        full = block["modes"]["full"]
        frames = full.get("frames", {}).get("orient_folded_within_45")
        oracle = full.get("frame_oracle", {}).get("orient_folded_within_45")
        diff = block.get("vs_first")
        lines.append(f"{name:<12}{full['mrr']:>7.3f}{full['top1']:>7.3f}{full['top5']:>7.3f}"
                     f"{100 * full['orient_folded_within_45']:>12.1f}%"
                     f"{100 * full['canonical']['orient_folded_within_45']:>10.1f}%"
                     + "".join(f"{100 * m:>7.1f}%" if m is not None else f"{'–':>8}" for m in (frames, oracle))
                     + f"{block.get('query_p50_ms', math.nan):>8.2f}{block.get('query_p95_ms', math.nan):>8.2f}"
                     + (f"  {diff['mrr_difference']:+.3f} [{diff['low']:+.3f}, {diff['high']:+.3f}]" if diff else ""))
    return lines


def _category_rows(result: dict, top: int) -> list[str]:
    names = list(result["engines"])
    first = result["engines"][names[0]]["categories"]
    order = sorted((c for c in first if "mrr" in first[c]), key=lambda c: (-first[c]["queries"], c))
    lines = [f"{'MRR by category':<24}{'n':>6}" + "".join(f"{n:>12}" for n in names)]
    for category in order[:top]:
        cells = [result["engines"][n]["categories"].get(category, {}).get("mrr", math.nan) for n in names]
        lines.append(f"{category:<24}{first[category]['queries']:>6}" + "".join(f"{v:>12.3f}" for v in cells))
    if len(order) > top:
        lines.append(f"… {len(order) - top} more categories (use --json for all)")
    return lines


def format_evaluation(result: dict, by_category: bool = False, top: int = 30) -> str:
    """A human table of :func:`evaluate`'s result (``by_category``: also the per-category tables)."""
    grouping = result["grouping"]
    how = (f"{result['folds']}-fold by scene, near-copies kept together ({grouping['groups']} groups; "
           f"{grouping['scenes_with_near_copies']} scenes have near-copies)" if grouping["group_similar"]
           else f"{result['folds']}-fold by scene")
    types = (", room types inferred without the object" if result.get("scene_type") == "inferred" else
             ", room types as the corpus gives them (a type inferred from the scene's objects counts the one asked "
             "about)")
    lines = [f"{result['source']}: {result['queries']} queries ({result['skipped']} skipped), {how}, "
             f"seed {result['seed']}{types}", "", f"the {result['engine']} engine",
             f"{'ranking':<14}{'MRR':>8}{'top-1':>8}{'top-5':>8}"]
    lines += _ranking_rows(result)
    full = result["modes"]["full"]
    sources = ", ".join(f"{n} from {s}" for s, n in sorted(result["period_sources"].items()))
    lines += ["", f"orientation of the true category ({full['orient_n']} placements; symmetry periods: {sources})"]
    lines += _orientation_rows(full)
    chairs = result["chairs_at_tables"]
    if chairs["n"]:
        lines += ["", f"chairs beside a table or desk ({chairs['n']}): facing it within 45° — "
                  + ", ".join(f"{label} {100 * chairs[f'{pose}_facing_within_45']:.1f}%"
                              for pose, label in (("full", "full"), ("paper", "paper's rule"),
                                                  ("canonical", "canonical")) if f"{pose}_facing_within_45" in chairs)]
    if len(result["engines"]) > 1:
        lines += ["", "engines on the same folds (MRR difference: paired bootstrap over scene groups)"]
        lines += _engine_rows(result)
    if "ungrouped" in result:
        plain = result["ungrouped"]
        lines += ["", f"plain {result['folds']}-fold by scene (near-copies may straddle folds; {plain['queries']} "
                      "queries)", f"{'ranking':<14}{'MRR':>8}{'top-1':>8}{'top-5':>8}"]
        lines += _ranking_rows(plain)
        lines += [""] + _orientation_rows(plain["modes"]["full"])
    if "ablations" in result:
        lines += ["", f"{'orientation ablations':<38}{'folded ≤15°':>12}{'≤45°':>8}{'median':>9}{'chairs facing':>15}"]
        rows = [(name, m, m["chairs_at_tables"]["full_facing_within_45"]) for name, m in result["ablations"].items()]
        if "paper" in full:
            rows += [("the paper's rule", full["paper"], chairs["paper_facing_within_45"])]
        rows += [("canonical pose (basic)", full["canonical"], chairs["canonical_facing_within_45"])]
        for name, m, facing in rows:
            lines.append(f"{name:<38}{100 * m['orient_folded_within_15']:>11.1f}%"
                         f"{100 * m['orient_folded_within_45']:>7.1f}%{m['orient_median_deg']:>8.1f}°"
                         f"{100 * facing:>14.1f}%")
    if by_category:
        poses_shown = [p for p in POSES if any(f"{p}_folded_within_45" in c for c in result["categories"].values())]
        lines += ["", f"{'folded ≤45°':<24}{'n':>6}{'period':>8}" + "".join(f"{p:>11}" for p in poses_shown)]
        shown = [(n, c) for n, c in result["categories"].items() if "period" in c]
        for name, c in shown[:top]:
            lines.append(f"{name:<24}{c['n']:>6}{c['period']:>7.0f}°"
                         + "".join(f"{100 * c[f'{p}_folded_within_45']:>10.1f}%" for p in poses_shown))
        if len(shown) > top:
            lines.append(f"… {len(shown) - top} more categories (use --json for all)")
        lines += [""] + _category_rows(result, top)
    return "\n".join(lines)


def explanation_lines(explained: list[dict]) -> list[str]:
    """An engine's explanation (its ``explain``), one block per category: score and the contributions to it."""
    lines = ["", "why (each category's score: the contributions that sum to it from the baseline)"]
    for e in sorted(explained, key=lambda e: e["rank"]):
        lines.append(f"{e['rank']:>4}. {e['category']:<22} score {e['score']:8.3f} = baseline {e['baseline']:.3f}"
                     " + …")
        for c in e["contributions"]:
            value = f"(value {c['value']:.3g})" if c["value"] is not None else ""
            lines.append(f"        {c['contribution']:+8.3f}  {c['feature']:<34} {value}")
    return lines


def _part(m: dict) -> str:
    return f"{m['mrr']:>7.3f} ({m['n']})" if m["n"] else f"{'–':>7} (0)"


def format_transfer(result: dict) -> str:
    """A human table of :func:`~scenesuggest.evaluation.transfer.evaluate_transfer`'s result."""
    walk = result["crosswalk"]
    types = "room types inferred without the object" if result["scene_type"] == "inferred" else \
        "room types as the corpus gives them"
    lines = [f"trained on {result['train']}, asked on {result['test']}: {result['queries']} queries "
             f"({result['unmapped_queries']} of unmapped categories left out, {result['skipped']} skipped), "
             f"seed {result['seed']}, {types}",
             f"categories mapped: {walk['mapped_categories']} of {walk['categories']} (by rule: "
             + ", ".join(f"{k} {v}" for k, v in sorted(walk["by_rule"].items(), key=lambda kv: -kv[1])) + ")",
             "unmapped queries: " + (", ".join(f"{c} {n}" for c, n in list(result["unmapped_by_category"].items())[:12])
                                     or "none"), "",
             f"{'engine':<12}{'MRR':>7}{'top-1':>7}{'top-5':>7}{'folded ≤45°':>13}{'known parents':>16}"
             f"{'unknown parents':>18}  MRR − {result['engine']} [95% CI]"]
    for name, block in result["engines"].items():
        full, diff = block["modes"]["full"], block.get("vs_first")
        lines.append(f"{name:<12}{full['mrr']:>7.3f}{full['top1']:>7.3f}{full['top5']:>7.3f}"
                     f"{100 * full['orient_folded_within_45']:>12.1f}%{_part(block['known_parents']):>16}"
                     f"{_part(block['unknown_parents']):>18}"
                     + (f"  {diff['mrr_difference']:+.3f} [{diff['low']:+.3f}, {diff['high']:+.3f}]" if diff else ""))
    if any("like_for_like" in b for b in result["engines"].values()):
        lines += ["", f"{'like for like':<12}{'in-corpus':>11}{'reweighted':>12}{'here':>8}{'kept':>8}"
                      f"{'ceiling':>10}{'kept there':>12}{'of ceiling':>12}"]
        for name, block in result["engines"].items():
            m = block["like_for_like"]
            ceiling = m["asked_corpus"]
            lines.append(f"{name:<12}{m['in_corpus_mrr']:>11.3f}{m['reweighted_in_corpus_mrr']:>12.3f}"
                         f"{m['cross_corpus_mrr']:>8.3f}{100 * m['kept']:>7.1f}%{ceiling['reweighted_mrr']:>10.3f}"
                         f"{100 * ceiling['kept']:>11.1f}%{100 * ceiling['of_ceiling']:>11.1f}%")
        lines.append("(ceiling: the engine trained by grouped folds on the asked corpus itself, in the training "
                     "corpus's categories; kept there: the ceiling over the reweighted in-corpus MRR)")
    for name, misses in result.get("explained_misses", {}).items():
        lines += ["", f"the {name} engine's worst misses"]
        for miss in misses:
            others = ", ".join(f"{e} {r:g}" if r is not None else f"{e} –" for e, r in miss["ranks"].items()
                               if e != name)
            lines += ["", f"{miss['category']} ({miss['as_named_there']} there) on {miss['parent']} "
                          f"{miss['parent_id']!r} in {miss['scene']} ({miss['scene_type']}): rank "
                          f"{miss['ranks'][name]:g}" + (f" ({others})" if others else "")]
            lines += explanation_lines(miss["explanation"])
    return "\n".join(lines)
