"""lme4 as the oracle of the mixed models, on studies nobody has seen: each run draws random studies (the seed is
in the test header; ``SCENESUGGEST_LME4_SEED=N`` repeats a run), fits every model the report fits in Python and
with R's lme4 (``tests/lme4_oracle.R``), and compares them at the tolerances of the lme4 reference data's README.

A study: 6–60 participants, three conditions, 2–8 scenes (each participant does up to three of them under every
condition), random effect sizes, some of them zero (condition effects and either variance component), drop-outs
and missing trials (unbalanced), log-normal times and Poisson counts with small means.

lme4 is run to convergence: lmer's BOBYQA to rhoend = 1e-12 (its default stops early where the likelihood is flat:
with two scenes a variance can be ~1% off), and Poisson fits on lme4's own deviance function restarted until its
inner solve converges (see tests/lme4_oracle.R and analysis/glmm.py). Tolerances
(``../shared/data/lme4_reference/README.md``): fixed effects and SEs rtol 1e-4 (or 1e-4 of a standard error, for an
estimate near zero); log-likelihoods atol 1e-4; LR χ² rtol 1e-4 or atol 1e-3; variance components rtol 1e-3, or
1e-6 of the residual variance (Gaussian; 1e-4 on the log scale for Poisson) for a component at zero. Poisson SEs
are compared for fits not on the boundary (a zero variance leaves no curvature to compare). glmer's default fit is
recorded beside (``default`` in the R output) but not held to anything: on small counts its vcov can be far off
(seed 304, study 1: SEs of 0.003 where the converged fit has 0.19).
"""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pandas as pd
import pytest
from support import LME4_SEED, ROOT, require_lme4

from analysis.design import build_design
from analysis.mixed import fit, lr_test, pairwise

STUDIES = 3  # random studies per run
SLOPE_STUDIES = 1  # random studies with random slopes per run (~45 s each: the Poisson GLMMs with 15 parameters)
LEVELS = ["none", "basic", "full"]


def random_study(rng: np.random.Generator, slopes: bool = False) -> tuple[pd.DataFrame, dict]:
    """A random study's trial table and the truth it was drawn from; with ``slopes``, the condition effects also
    vary by participant and by scene (random slopes, drawn from a stream of their own, so that a study without
    them is the same study as before)."""
    n_people, n_scenes = int(rng.integers(6, 61)), int(rng.integers(2, 9))
    maybe_zero = lambda low, high: 0.0 if rng.random() < 0.25 else float(rng.uniform(low, high))  # noqa: E731
    truth = {"participants": n_people, "scenes": n_scenes,
             "effects": [0.0] + [maybe_zero(-0.4, 0.4) for _ in range(2)],
             "sd_participant": maybe_zero(0.05, 0.5), "sd_scene": maybe_zero(0.05, 0.4),
             "sd_residual": float(rng.uniform(0.1, 0.5)), "mean_queries": float(rng.uniform(0.3, 4.0)),
             "p_missing": float(rng.uniform(0, 0.15)), "p_drop_out": float(rng.uniform(0, 0.3))}
    scenes = [f"S{i + 1}" for i in range(n_scenes)]
    b_scene = dict(zip(scenes, rng.normal(0, truth["sd_scene"], n_scenes), strict=True))
    c_scene = dict(zip(scenes, rng.normal(0, truth["sd_scene"], n_scenes), strict=True))
    slope = np.random.default_rng(rng.integers(2**63)) if slopes else None  # its own stream: see above
    if slopes:
        truth["sd_slope_participant"], truth["sd_slope_scene"] = (0.0 if slope.random() < 0.2 else
                                                                  float(slope.uniform(0.05, 0.4)) for _ in range(2))
        s_scene = {s: np.r_[0.0, slope.normal(0, truth["sd_slope_scene"], 2)] for s in scenes}
    rows = []
    for p in range(n_people):
        own = rng.choice(scenes, size=min(3, n_scenes), replace=False)
        plan = [(c, s) for c in rng.permutation(3) for s in own]
        if rng.random() < truth["p_drop_out"]:
            plan = plan[:int(rng.integers(1, len(plan)))]
        b_p, c_p = rng.normal(0, truth["sd_participant"], 2)
        s_p = np.r_[0.0, slope.normal(0, truth["sd_slope_participant"], 2)] if slopes else np.zeros(3)
        for c, s in plan:
            if rng.random() < truth["p_missing"]:
                continue
            effect = truth["effects"][c] + s_p[c] + (s_scene[s][c] if slopes else 0.0)
            log_t = np.log(300) + effect + b_p + b_scene[s] + rng.normal(0, truth["sd_residual"])
            rate = truth["mean_queries"] * np.exp(effect + c_p + c_scene[s])
            rows.append({"participant": f"P{p + 1:02d}", "scene": s, "condition": LEVELS[c],
                         "total_time": round(float(np.exp(log_t)), 3), "n_queries": int(rng.poisson(rate))})
    return pd.DataFrame(rows), truth


def python_fits(d: pd.DataFrame) -> dict:
    d = d.assign(condition=pd.Categorical(d["condition"], LEVELS), log_time=np.log(d["total_time"]))
    crossed, one = ["participant", "scene"], ["participant"]

    def design(response, fixed, random):
        return build_design(d, response, fixed, random)

    time_full = design("total_time", ["condition"], crossed)
    log_full = design("log_time", ["condition"], crossed)
    queries = design("n_queries", ["condition"], crossed)
    by_participant = design("n_queries", ["condition"], one)
    return {
        "time_ml": fit(time_full), "time_ml_null": fit(time_full.without("condition")),
        "time_reml": fit(time_full, reml=True),
        "log_time_ml": fit(log_full), "log_time_ml_null": fit(log_full.without("condition")),
        "queries": fit(queries, "poisson"), "queries_null": fit(queries.without("condition"), "poisson"),
        "queries_laplace_participant": fit(by_participant, "poisson"),
        "queries_agq_participant": fit(by_participant, "poisson", n_agq=10),
    }


#: Two optima this close in log-likelihood are one (the deviance's rounding is ~1e-13 of ~1e3)
TIE = 1e-9
#: The random-slope structures compared with lme4 (``--random`` specs; lme4's formulas in tests/lme4_oracle.R)
SLOPES = {"maximal": ["condition|participant", "condition|scene"],
          "uncorrelated": ["condition||participant", "condition||scene"],
          "by_participant": ["condition|participant", "scene"]}
#: The Poisson GLMMs with slopes compared (by Laplace; tests/lme4_oracle.R with "poisson" fits the same three)
POISSON_SLOPES = tuple(SLOPES)


def python_slope_fits(d: pd.DataFrame) -> tuple[dict, dict]:
    """Our fits of the slope models, and their designs, by the names tests/lme4_oracle.R gives them."""
    d = d.assign(condition=pd.Categorical(d["condition"], LEVELS), log_time=np.log(d["total_time"]))
    out, designs = {}, {}
    for name, random in SLOPES.items():
        design = build_design(d, "log_time", ["condition"], random)
        designs[f"time_{name}"] = designs[f"time_{name}_reml"] = design
        designs[f"time_{name}_null"] = design.without("condition")
        out[f"time_{name}"], out[f"time_{name}_null"] = fit(design), fit(design.without("condition"))
        out[f"time_{name}_reml"] = fit(design, reml=True)
    for name in POISSON_SLOPES:
        design = build_design(d, "n_queries", ["condition"], SLOPES[name])
        designs[f"queries_{name}"], designs[f"queries_{name}_null"] = design, design.without("condition")
        out[f"queries_{name}"] = fit(design, "poisson")
        out[f"queries_{name}_null"] = fit(design.without("condition"), "poisson")
    return out, designs


def lme4_parameters(fitted, design) -> dict:
    """A fit's θ by lme4's names (``group.row`` on a factor's diagonal, ``group.row.column`` below it) and β."""
    from analysis.random_effects import theta_layout

    names = [f"{t.group}.{t.names[r]}" if r == c else f"{t.group}.{t.names[r]}.{t.names[c]}"
             for t in design.random for r, c in theta_layout([t])]
    return {"theta": dict(zip(names, fitted.theta, strict=True)), "beta": list(fitted.fixed.values())}


def saturated_loglik(y: np.ndarray) -> float:
    """Σ log Pois(y | y): lme4 reports the log-likelihood of an nAGQ > 1 fit less this."""
    from scipy.special import gammaln

    return float((y * np.log(np.where(y > 0, y, 1)) - y - gammaln(y + 1)).sum())


def near(a, b, tolerance: float) -> bool:
    """|a − b| ≤ tolerance, and both are numbers (a NaN on either side is a difference, never a pass)."""
    return a is not None and b is not None and math.isfinite(a) and math.isfinite(b) and abs(a - b) <= tolerance


def compare(name: str, ours, theirs: dict, *, saturated: float = 0.0, shape: bool = True) -> list[str]:
    """What differs between our fit and lme4's, beyond the tolerances (empty when they agree). ``shape``: also
    the correlations, the singular flag and lme4's messages — what a flat likelihood may leave undetermined."""
    problems = []
    gaussian = ours.family == "gaussian"
    loglik = -theirs["REMLcrit"] / 2 if ours.reml else theirs["logLik"] + saturated
    if not near(ours.loglik, loglik, 1e-4):
        problems.append(f"{name}: logLik {ours.loglik!r} vs lme4 {loglik!r}")
    if list(ours.fixed) != list(theirs["fixef"]):
        return problems + [f"{name}: fixed effects {list(ours.fixed)} vs lme4 {list(theirs['fixef'])}"]
    singular = ours.singular or theirs["singular"]
    ses = theirs["se"]  # Poisson: from lme4's converged deviance (None when its Hessian has no inverse)
    if ses is None and not singular:
        problems.append(f"{name}: lme4's converged Hessian could not be inverted")
    for term, value in ours.fixed.items():
        se = (ses or theirs["se_glmer"])[term]
        if not near(value, theirs["fixef"][term], 1e-4 * max(abs(theirs["fixef"][term]), se)):
            problems.append(f"{name}: {term} {value!r} vs lme4 {theirs['fixef'][term]!r} (SE {se:.3g})")
        # lmer's vcov comes from its fit's RX, defined at a singular fit too; a Poisson SE needs curvature in θ
        if ses and (gaussian or not singular) and not near(ours.se[term], se, 1e-4 * se):
            problems.append(f"{name}: SE of {term} {ours.se[term]!r} vs lme4 {se!r}")
    residual = theirs["varcomp"].get("residual", 0.0)
    floor = 1e-6 * residual if gaussian else 1e-4
    if set(ours.variance) != set(theirs["varcomp"]):
        return problems + [f"{name}: components {sorted(ours.variance)} vs lme4 {sorted(theirs['varcomp'])}"]
    for group, value in theirs["varcomp"].items():
        if ":cor(" in group:
            if not shape:
                continue
            # a correlation is compared where both its variances are determined (above the floor a hundredfold):
            # of a variance at zero it is arbitrary, and lme4's and these optimisers leave it where they stop
            grp, pair = group.split(":cor(")
            sides = [grp if side == "(Intercept)" else f"{grp}:{side}" for side in pair[:-1].split(",")]
            if min(theirs["varcomp"][side] for side in sides) > 100 * floor \
                    and not near(ours.variance[group], value, 1e-3):
                problems.append(f"{name}: correlation {group} {ours.variance[group]!r} vs lme4 {value!r}")
        elif not near(ours.variance[group], value, max(1e-3 * abs(value), floor)):
            problems.append(f"{name}: variance of {group} {ours.variance[group]!r} vs lme4 {value!r}")
    if not shape:
        return problems
    theta = np.atleast_1d(theirs.get("theta", []))  # (a single θ comes as a number)
    # lme4's lower bounds: 0 on a factor's diagonal, "-Inf" (as jsonlite writes it) below
    diagonal = np.array([float(v) for v in np.atleast_1d(theirs.get("lower", np.zeros_like(theta)))]) == 0
    borderline = bool(np.any((np.abs(theta) > 0.5e-4) & (np.abs(theta) < 2e-4) & diagonal))
    if ours.singular != theirs["singular"] and not borderline:
        problems.append(f"{name}: singular {ours.singular} vs lme4 {theirs['singular']}")
    messages = theirs.get("messages")
    if gaussian and messages is not None and not borderline and list(ours.messages) != np.atleast_1d(messages).tolist():
        problems.append(f"{name}: lme4's messages {ours.messages} vs lme4 {messages}")
    return problems


def lr_problems(name: str, ours, theirs_full: dict, theirs_null: dict, df: int) -> list[str]:
    chi2 = max(0.0, 2 * (theirs_full["logLik"] - theirs_null["logLik"]))
    if ours.df != df or not near(ours.chi2, chi2, max(1e-4 * chi2, 1e-3)):
        return [f"{name}: LR χ²({ours.df}) {ours.chi2!r} vs lme4 χ²({df}) {chi2!r}"]
    return []


@pytest.mark.parametrize("study", range(STUDIES))
@pytest.mark.slow
def test_every_model_of_the_report_matches_lme4_on_a_random_study(study, tmp_path):
    rscript = require_lme4()
    seed = [LME4_SEED, study]
    data, truth = random_study(np.random.default_rng(seed))
    csv = tmp_path / f"lme4-oracle-{LME4_SEED}-{study}.csv"
    data.to_csv(csv, index=False)
    where = (f"seed {LME4_SEED}, study {study} (SCENESUGGEST_LME4_SEED={LME4_SEED} repeats it); data: {csv}; "
             f"drawn from {json.dumps(truth)}")
    ran = subprocess.run([rscript, str(ROOT / "tests" / "lme4_oracle.R"), str(csv), str(tmp_path / "lme4.json")],
                         capture_output=True, text=True, timeout=600)
    assert ran.returncode == 0, f"lme4 failed on {where}:\n{ran.stderr[-2000:]}"
    lme4 = json.loads((tmp_path / "lme4.json").read_text())
    ours = python_fits(data)
    agq_offset = saturated_loglik(data["n_queries"].to_numpy(float))
    problems = []
    for name, fitted in ours.items():
        problems += compare(name, fitted, lme4[name], saturated=agq_offset if name.endswith("agq_participant") else 0)
    for full, null in (("time_ml", "time_ml_null"), ("log_time_ml", "log_time_ml_null"), ("queries", "queries_null")):
        problems += lr_problems(full, lr_test(ours[null], ours[full]), lme4[full], lme4[null], 2)
    assert not problems, f"{len(problems)} difference(s) from lme4 on {where}:\n" + "\n".join(problems)


@pytest.mark.parametrize("study", range(SLOPE_STUDIES))
@pytest.mark.slow
def test_random_slope_models_match_lme4_on_a_random_study(study, tmp_path):
    """Maximal, uncorrelated and participant-only random slopes of condition: LMM (ML, REML) and Poisson GLMM
    (Laplace), each with the LR test of condition and the pairwise contrasts, against lme4 run to convergence."""
    rscript = require_lme4()
    seed = [LME4_SEED, 100 + study]
    data, truth = random_study(np.random.default_rng(seed), slopes=True)
    csv = tmp_path / f"lme4-slopes-{LME4_SEED}-{study}.csv"
    data.to_csv(csv, index=False)
    where = (f"seed {LME4_SEED}, slope study {study} (SCENESUGGEST_LME4_SEED={LME4_SEED} repeats it); data: {csv}; "
             f"drawn from {json.dumps(truth)}")
    ran = subprocess.run([rscript, str(ROOT / "tests" / "lme4_oracle.R"), str(csv), str(tmp_path / "lme4.json"),
                          "slopes", "poisson"], capture_output=True, text=True, timeout=900)
    assert ran.returncode == 0, f"lme4 failed on {where}:\n{ran.stderr[-2000:]}"
    lme4 = json.loads((tmp_path / "lme4.json").read_text())
    ours, designs = python_slope_fits(data)
    # A fit above lme4's best optimum by more than the tolerance is checked in lme4 itself: its own likelihood at
    # our parameters. If that is our log-likelihood, ours is a better optimum of the same likelihood (lme4's BOBYQA
    # stops early on the flat, singular surfaces of random slopes), and that model, its LR test and contrasts are
    # not compared further; anything else is a difference. A fit that agrees with lme4's in all but its shape (a
    # correlation, whether it is singular, lme4's messages) and is at least as high (to TIE) is checked the same way:
    # if lme4's likelihood rates our parameters at least as high as its optimum, both are optima of a surface flat
    # where they differ (a correlation that moves by 1e-3, or a variance between 0 and 1e-3, for 1e-7 of
    # log-likelihood), and only the shape is not compared.
    optimum = {name: -lme4[name]["REMLcrit"] / 2 if fitted.reml else lme4[name]["logLik"]
               for name, fitted in ours.items()}
    found = {name: compare(name, fitted, lme4[name]) for name, fitted in ours.items()}
    flat = {name for name, fitted in ours.items() if found[name] and fitted.loglik >= optimum[name] - TIE
            and not compare(name, fitted, lme4[name], shape=False)}
    check = {name: lme4_parameters(fitted, designs[name]) for name, fitted in ours.items()
             if fitted.loglik > optimum[name] + 1e-4 or name in flat}
    better, problems, at_values = set(), [], {}
    if check:
        (tmp_path / "at.json").write_text(json.dumps(check))
        at = subprocess.run([rscript, str(ROOT / "tests" / "lme4_oracle.R"), str(csv), str(tmp_path / "at-out.json"),
                             "at", str(tmp_path / "at.json")], capture_output=True, text=True, timeout=900)
        assert at.returncode == 0, f"lme4 failed on {where}:\n{at.stderr[-2000:]}"
        at_values = json.loads((tmp_path / "at-out.json").read_text())
        for name, value in at_values.items():
            confirmed = near(value, ours[name].loglik, 1e-4) and value >= optimum[name] - TIE
            if name in flat:
                if confirmed:
                    found[name] = []
            elif confirmed:
                better.add(name)
            else:
                problems.append(f"{name}: logLik {ours[name].loglik!r} above lme4's optimum {optimum[name]!r}, but "
                                f"lme4's likelihood at our parameters is {value!r}")
    for name in ours:
        if name not in better:
            problems += found[name]
    # the LR tests from lme4's log-likelihoods: at its optimum, or at ours where ours is the better one
    assert len(better) <= 2, f"lme4 stopped short of our optimum on {sorted(better)} ({where})"
    lme4_at = {name: {**lme4[name], "logLik": at_values[name]} if name in better else lme4[name] for name in lme4
               if name != "versions"}
    for name in [f"time_{s}" for s in SLOPES] + [f"queries_{s}" for s in POISSON_SLOPES]:
        test = lr_test(ours[f"{name}_null"], ours[name])
        problems += lr_problems(name, test, lme4_at[name], lme4_at[f"{name}_null"], 2)
        if name not in better and lme4[name]["vcov"] is not None \
                and not (ours[name].singular and name.startswith("queries")):
            problems += contrast_problems(name, ours[name], lme4[name])
    assert not problems, f"{len(problems)} difference(s) from lme4 on {where}:\n" + "\n".join(problems)


def contrast_problems(name: str, ours, theirs: dict) -> list[str]:
    """Every pairwise contrast of condition (estimate and SE, from lme4's fixef and vcov) against pairwise()."""
    beta, cov = np.array(list(theirs["fixef"].values())), np.array(theirs["vcov"])
    index = {"none": None, "basic": 1, "full": 2}
    problems = []
    for contrast in pairwise(ours, "condition", LEVELS):
        c = np.zeros(3)
        for level, sign in ((contrast.a, 1), (contrast.b, -1)):
            if index[level] is not None:
                c[index[level]] += sign
        estimate, se = float(c @ beta), float(np.sqrt(c @ cov @ c))
        if not (near(contrast.estimate, estimate, 1e-4 * max(abs(estimate), se)) and near(contrast.se, se, 1e-4 * se)):
            problems.append(f"{name}: {contrast.a} − {contrast.b} {contrast.estimate!r} ± {contrast.se!r} "
                            f"vs lme4 {estimate!r} ± {se!r}")
    return problems


def test_the_oracle_studies_cover_what_they_claim():
    """Across 200 draws the generator makes every kind of study the oracle is meant to see."""
    truths, sizes = [], []
    for i in range(200):
        data, truth = random_study(np.random.default_rng([0, i]))
        truths.append(truth)
        per_person = data.groupby("participant").size()
        sizes.append((data["participant"].nunique(), data["scene"].nunique(), per_person.nunique() > 1,
                      data["n_queries"].mean()))
    people = [t["participants"] for t in truths]
    assert min(people) == 6 and max(people) >= 55 and {t["scenes"] for t in truths} == set(range(2, 9))
    assert any(t["sd_participant"] == 0 for t in truths) and any(t["sd_scene"] == 0 for t in truths)
    assert any(0.0 in t["effects"][1:] for t in truths) and any(all(t["effects"][1:]) for t in truths)
    assert sum(unbalanced for _, _, unbalanced, _ in sizes) > 100  # drop-outs and missing trials
    assert min(mean for *_, mean in sizes) < 0.6  # counts with small means

