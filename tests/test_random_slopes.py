"""Random slopes: the ``--random`` grammar and the terms it makes, random effects the data cannot support refused
by name, the linear mixed model's exact gradient, and lme4's singularity and convergence checks in its words.
(The numbers against lme4 are in tests/test_lme4_oracle.py.)"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from test_lme4_oracle import random_study

from analysis import AnalysisError
from analysis.convergence import SINGULAR, is_singular, messages
from analysis.design import build_design, formula_of
from analysis.mixed import fit
from analysis.results import format_p

LEVELS = ["none", "basic", "full"]


@pytest.fixture(scope="module")
def study() -> pd.DataFrame:
    data, _ = random_study(np.random.default_rng([7, 0]), slopes=True)
    return data.assign(condition=pd.Categorical(data["condition"], LEVELS), log_time=np.log(data["total_time"]),
                       practice=np.arange(len(data)) % 5 * 0.5)


@pytest.mark.parametrize("random,formula", [
    (["participant", "scene"], "(1 | participant) + (1 | scene)"),
    (["condition|participant", "scene"], "(1 + conditionbasic + conditionfull | participant) + (1 | scene)"),
    (["condition||participant"], "(1 | participant) + (0 + conditionbasic | participant) + "
                                 "(0 + conditionfull | participant)"),
    (["0 + condition|participant"], "(0 + conditionnone + conditionbasic + conditionfull | participant)"),
    (["1 + practice|participant"], "(1 + practice | participant)"),
    (["condition + practice|scene"], "(1 + conditionbasic + conditionfull + practice | scene)"),
])
def test_random_terms_read_as_lme4_writes_them(study, random, formula):
    design = build_design(study, "log_time", ["condition"], random)
    assert formula_of(design) == f"log_time ~ condition + {formula}"


def test_a_factors_slope_is_coded_as_its_fixed_effect(study):
    """--reference reorders the fixed effect's levels, and the slope's dummies follow it."""
    design = build_design(study, "log_time", ["condition"], ["condition|participant"], reference="full")
    assert design.fixed_names == ("(Intercept)", "conditionnone", "conditionbasic")
    assert design.random[0].names == ("(Intercept)", "conditionnone", "conditionbasic")
    column = design.random[0].columns()[:, 1]
    assert np.array_equal(column, (study["condition"] == "none").to_numpy(float))


def test_an_infinite_slope_value_is_missing_like_an_empty_cell(study):
    bad = study.assign(practice=study["practice"].where(study.index != 3, np.inf))
    design = build_design(bad, "log_time", ["condition"], ["practice|participant"])
    assert design.nobs == len(study) - 1 and design.dropped == 1


def test_uncorrelated_slopes_are_terms_of_their_own_and_fit_as_independent_variances(study):
    design = build_design(study, "log_time", ["condition"], ["condition||participant", "scene"])
    assert [(t.group, t.names) for t in design.random] == [
        ("participant", ("(Intercept)",)), ("participant", ("conditionbasic",)),
        ("participant", ("conditionfull",)), ("scene", ("(Intercept)",))]
    fitted = fit(design)
    assert set(fitted.variance) == {"participant", "participant:conditionbasic", "participant:conditionfull",
                                    "scene", "residual"}
    assert fitted.n_params == 3 + 4 + 1


@pytest.mark.parametrize("random,message", [
    (["condition|participant", "participant"], "repeats the effect (Intercept)"),
    (["group_condition|participant"], "never varies within a level of participant"),
    (["condition|trial"], "random effects for"),
    (["nope|participant"], "no column 'nope'"),
    (["condition|nope"], "no column 'nope'"),
    (["condition + |participant"], "has an empty term"),
    (["0|participant"], "has no random effect"),
    (["condition + condition|participant"], "names a column twice"),
    (["a|b|participant"], "is not a random term"),
    (["condition|"], "is not a random term"),
    (["one_level|participant"], "a random slope needs at least 2"),
    (["(1|participant)"], "without lme4's parentheses"),
    (["condition|one_level"], "one_level has 1 level(s) with data; a grouping factor needs at least 2"),
    (["participant|scene"], "at most 10 are fitted"),
    (["+".join(["practice"] * 5000) + "|participant"], "names 5000 terms; at most 10 random effects"),
    (["(" * 100_000], "write a random term without lme4's parentheses"),
])
def test_random_effects_the_design_cannot_support_are_refused_by_name(study, random, message):
    """A between-participant column's slope by participant, as many effects as observations, a term twice: a
    clear error naming the term, never a numerical failure."""
    data = study.assign(group_condition=study["participant"].map(lambda p: "a" if int(p[1:]) % 2 else "b"),
                        trial=np.arange(len(study)).astype(str), one_level="x")
    with pytest.raises(AnalysisError, match=message.replace("(", r"\(").replace(")", r"\)")) as raised:
        build_design(data, "log_time", ["condition"], random)
    assert len(raised.value.message) < 400  # a huge spec is quoted by its start


@pytest.mark.parametrize("random", [["condition|participant", "condition|scene"], ["condition||participant", "scene"],
                                    ["participant", "scene"]])
@pytest.mark.parametrize("reml", [False, True])
def test_the_lmm_gradient_is_the_deviances_derivative(study, random, reml):
    from analysis.lmm import _Profiled

    model = _Profiled(build_design(study, "log_time", ["condition"], random), reml)
    rng = np.random.default_rng(3)
    for _ in range(3):
        theta = np.where(model.effects.diagonal, rng.uniform(0.1, 2, len(model.bounds)),
                         rng.normal(0, 0.7, len(model.bounds)))
        value, gradient = model.deviance_and_gradient(theta)
        assert value == pytest.approx(model.deviance(theta), abs=1e-9)
        step = 1e-5
        numeric = [(model.deviance(theta + e) - model.deviance(theta - e)) / (2 * step)
                   for e in np.eye(len(theta)) * step]
        assert gradient == pytest.approx(numeric, rel=1e-5, abs=1e-4)


@pytest.mark.parametrize("random", [["condition|participant", "condition|scene"], ["condition||participant", "scene"],
                                    ["participant", "scene"], ["scene", "condition|participant"],
                                    ["condition|participant", "0 + practice|participant", "scene"]])
def test_the_poisson_gradient_is_the_laplace_deviances_derivative(study, random):
    """The exact gradient in (θ, β), through the conditional modes and the leverages, against central differences —
    on crossed and single factors, the largest factor named second, and two terms stacked on one factor."""
    from analysis.glmm import _Laplace

    model = _Laplace(build_design(study, "n_queries", ["condition"], random), 1)
    rng = np.random.default_rng(4)
    for _ in range(3):
        theta = np.where(model.z.diagonal, rng.uniform(0.1, 0.8, model.k), rng.normal(0, 0.3, model.k))
        x = np.concatenate([theta, rng.normal(0, 0.3, model.p)])
        value, gradient = model.deviance_and_gradient(x)
        assert value == pytest.approx(model.deviance(x), abs=1e-9)
        step = 1e-5
        numeric = [(model.deviance(x + e) - model.deviance(x - e)) / (2 * step) for e in np.eye(len(x)) * step]
        assert gradient == pytest.approx(numeric, rel=1e-5, abs=1e-4)


def test_the_leverages_are_the_diagonal_of_the_dense_hat_matrix(study):
    """diag(ZΛH⁻¹Λ'Z') through the Schur complement equals the same from dense matrices."""
    from analysis.random_effects import RandomEffects

    design = build_design(study, "n_queries", ["condition"], ["condition|participant", "condition|scene"])
    effects = RandomEffects(design.random)
    rng = np.random.default_rng(5)
    theta = np.where(effects.diagonal, rng.uniform(0.2, 1, effects.n_theta), rng.normal(0, 0.4, effects.n_theta))
    w = rng.uniform(0.5, 3, design.nobs)
    zl = np.column_stack([effects.zl_u(theta, e) for e in np.eye(effects.q)])  # ZΛ, column by column
    dense = zl @ np.linalg.solve(zl.T @ (w[:, None] * zl) + np.eye(effects.q), zl.T)
    assert effects.leverages(theta, effects.curvature(theta, effects.crosstabs(w))) == \
        pytest.approx(np.diag(dense), rel=1e-9, abs=1e-12)


def test_the_ways_off_a_zero_diagonal_keep_the_covariance_and_the_parameters():
    """Each point turns or rotates a factor's column at zero without changing TT' but for the small diagonal it
    sets, and writes only where θ has an entry: an uncorrelated block gets the plain scan alone."""
    from analysis.optimum import SCAN
    from analysis.random_effects import RandomEffects

    study = _slope_study([11, 0])
    for random, turns in ((["condition|participant", "scene"], True), (["condition||participant", "scene"], False)):
        effects = RandomEffects(build_design(study, "log_time", ["condition"], random).random)
        theta = np.where(effects.diagonal, 0.5, 0.3)
        theta[np.flatnonzero(effects.diagonal)[1]] = 0.0  # the participant factor's second diagonal at zero
        beta = np.array([1.0, 2.0])
        x = np.concatenate([theta, beta])
        points = list(effects.ways_off_zero(x))
        assert points and all(np.array_equal(p[len(theta):], beta) for p in points)
        before = effects.factors(x)[0]
        for p in points:
            after = effects.factors(p)[0]
            assert after[1, 1] in SCAN
            back = after.copy()
            back[1, 1] = 0.0  # the diagonal set off zero, back at zero: the same covariance
            assert back @ back.T == pytest.approx(before @ before.T, abs=1e-9)
            held = np.zeros_like(after)
            rows, cols = effects.groups[0].rows, effects.groups[0].cols
            held[rows, cols] = after[rows, cols]
            assert np.array_equal(held, after)  # nothing where θ has no entry
        assert bool(list(effects.ways_off_zero(x, (0.01,), plain=False))) == turns


def test_a_correlation_at_one_is_a_singular_fit_as_in_lme4():
    diagonal = np.array([True, False, True])
    assert not is_singular(np.array([0.5, 0.2, 0.3]), diagonal)
    assert is_singular(np.array([0.5, 0.2, 0.0]), diagonal)  # the slope is the intercept times 0.4: cor = 1
    assert is_singular(np.array([0.0, 0.2, 0.3]), diagonal)  # no intercept variance
    assert not is_singular(np.array([0.5, 0.0, 0.3]), diagonal)  # an off-diagonal zero is a correlation of 0


def test_convergence_is_checked_as_lme4_checks_it_in_its_words():
    diagonal = np.array([True, True])
    theta, hessian = np.array([0.5, 0.4]), np.array([[4.0, 0.5], [0.5, 2.0]])
    assert messages(np.array([0.5, 0.0]), diagonal, np.array([9.0, 9.0]), hessian) == [SINGULAR]
    assert messages(theta, diagonal, np.array([1e-6, -2e-6]), hessian) == []
    failed = messages(theta, diagonal, np.array([1e-6, 0.05]), hessian)
    # R: H <- matrix(c(4, .5, .5, 2), 2); s <- solve(chol(H), c(1e-6, .05)); max(pmin(abs(s), abs(g))) = 0.0359211
    # (lme4 says "component 1" whichever it is)
    assert failed == ["Model failed to converge with max|grad| = 0.0359211 (tol = 0.002, component 1)"]
    assert messages(theta, diagonal, np.array([np.nan, 0.0]), hessian) == ["Gradient contains NAs"]
    assert messages(theta, diagonal, np.zeros(2), np.array([[1.0, 0.0], [0.0, -1.0]]))[-1] == \
        "Model failed to converge: degenerate  Hessian with 1 negative eigenvalues"
    assert messages(theta, diagonal, np.zeros(2), np.diag([1.0, 1e-7]))[-1] == \
        " Hessian is numerically singular: parameters are not uniquely determined"
    assert messages(theta, diagonal, np.zeros(2), np.diag([10.0, 5e-6]))[-1] == \
        "Model is nearly unidentifiable: large eigenvalue ratio\n - Rescale variables?"


def test_fits_carry_lme4s_messages(study):
    from analysis.convergence import SINGULAR_TOL

    design = build_design(study, "log_time", ["condition"], ["condition|participant", "condition|scene"])
    lmm = fit(design)
    diagonal = [r == c for t in design.random for c in range(t.width) for r in range(c, t.width)]
    smallest = min(abs(t) for t, d in zip(lmm.theta, diagonal, strict=True) if d)
    assert lmm.singular == (smallest < SINGULAR_TOL) and lmm.messages == ((SINGULAR,) if lmm.singular else ())
    intercepts = fit(build_design(study, "log_time", ["condition"], ["participant"]))
    assert intercepts.messages == () and not intercepts.singular and min(intercepts.theta) > SINGULAR_TOL


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "analyze", *args], capture_output=True,
                          text=True, env=dict(os.environ))


def test_the_cli_fits_random_slopes_and_refuses_what_it_cannot_fit(study, tmp_path):
    csv = tmp_path / "trials.csv"
    study.to_csv(csv, index=False)
    run = _cli("lmm", str(csv), "--response", "total_time", "--fixed", "condition", "--random",
               "condition|participant", "--random", "scene", "--reference", "none", "--json")
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["formula"] == ("total_time ~ condition + (1 + conditionbasic + conditionfull | participant) + "
                              "(1 | scene)")
    assert "participant:cor((Intercept),conditionbasic)" in out["variance"]
    assert out["lrt"]["df"] == 2 and isinstance(out["messages"], list)
    text = _cli("lmm", str(csv), "--response", "total_time", "--fixed", "condition",
                "--random", "condition||participant", "--random", "scene", "--reference", "none")
    assert text.returncode == 0 and "(0 + conditionfull | participant)" in text.stdout
    poisson = _cli("lmm", str(csv), "--response", "n_queries", "--family", "poisson", "--fixed", "condition",
                   "--random", "condition|participant", "--random", "scene", "--reference", "none", "--json")
    assert poisson.returncode == 0, poisson.stderr
    counts = json.loads(poisson.stdout)
    assert counts["formula"] == ("n_queries ~ condition + (1 + conditionbasic + conditionfull | participant) + "
                                 "(1 | scene)") and counts["lrt"]["df"] == 2
    assert "participant:cor((Intercept),conditionfull)" in counts["variance"]
    study.assign(group=study["participant"].str[-1]).to_csv(csv, index=False)
    bad = _cli("lmm", str(csv), "--response", "total_time", "--fixed", "condition", "--random", "participant|group")
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert "participant" in bad.stderr and "group" in bad.stderr


def _slope_study(seed: int) -> pd.DataFrame:
    data, _ = random_study(np.random.default_rng(seed), slopes=True)
    return data.assign(condition=pd.Categorical(data["condition"], LEVELS), log_time=np.log(data["total_time"]))


def test_the_structure_is_chosen_by_the_stated_rule_step_by_step():
    """Maximal first; a singular or unconverged fit loses its correlations, then the slope with the smallest variance
    of that fit, one at a time; the first fit that is neither is kept and tested; intercepts are the floor."""
    from analysis.selection import choose

    for seed in ([11, 0], [11, 3]):
        chosen = choose(_slope_study(seed), "log_time", "gaussian")
        steps = chosen.steps
        assert steps[0].structure == "correlated slopes of basic, full by participant; basic, full by scene"
        for before, after in zip(steps, steps[1:], strict=False):
            assert before.singular or before.messages
            if before.structure.startswith("correlated"):
                assert before.decision.endswith("leave out the correlations")
                assert after.structure.startswith("uncorrelated")
            elif after.structure != "intercepts only" or "slope" in before.decision:
                smallest = min((v, k) for k, v in before.variances.items()
                               if ":" in k and k.split(":")[0] in ("participant", "scene"))
                group, slope = smallest[1].split(":")
                assert f"the slope of {slope.removeprefix('condition')} by {group}" in before.decision
        last = steps[-1]
        assert last.decision.startswith("kept")
        assert chosen.comparison.full.formula == last.formula or last.structure == "intercepts only"
        assert (not last.messages) or last.structure == "intercepts only" or \
            "singular only in a random intercept" in last.decision
        assert chosen.comparison.lrt.df == 2


def test_the_kept_models_test_is_set_beside_the_intercept_only_test():
    from analysis.selection import choose

    chosen = choose(_slope_study([11, 1]), "log_time", "gaussian")
    assert chosen.kept.name() == "uncorrelated slopes of basic, full by participant; basic, full by scene"
    p, p0 = chosen.comparison.lrt.p, chosen.intercepts.lrt.p
    assert p0 < 0.05 < p  # varying effects between people and scenes: intercepts alone are anti-conservative
    assert chosen.sentence() == (f"With random intercepts only, the test of condition gives {format_p(p0)} against "
                                 f"{format_p(p)} under the uncorrelated slopes of basic, full by participant; basic, "
                                 "full by scene: a different conclusion at α = .05.")
    assert chosen.intercepts.full.formula.endswith("(1 | participant) + (1 | scene)")


def test_a_fit_singular_only_in_a_random_intercept_keeps_its_slopes():
    """Scenes that explain nothing (their intercept's variance at zero) do not strip participants' slopes: the rule
    never leaves an intercept out, so a fit singular only there is kept, and marked singular."""
    from analysis.selection import choose

    rng = np.random.default_rng(1)
    rows = []
    for p in range(40):
        intercept, slopes = rng.normal(0, 0.3), np.r_[0.0, rng.normal(0, 0.3, 2)]
        rows += [{"participant": f"P{p}", "scene": f"S{(k + c + p) % 3}", "condition": LEVELS[c],
                  "log_time": 5 + (0, -0.2, -0.3)[c] + intercept + slopes[c] + rng.normal(0, 0.2)}
                 for c in range(3) for k in range(3)]
    data = pd.DataFrame(rows).assign(condition=lambda d: pd.Categorical(d["condition"], LEVELS))
    chosen = choose(data, "log_time", "gaussian")
    assert chosen.kept.name() == "uncorrelated slopes of basic, full by participant"
    assert chosen.steps[-1].decision == ("kept: converged, singular only in a random intercept (scene), which the "
                                         "rule keeps")
    assert chosen.comparison.full.singular and chosen.comparison.full.variance["scene"] < 1e-8
    assert min(chosen.comparison.full.variance[f"participant:condition{lv}"] for lv in LEVELS[1:]) > 0.01


def test_a_slope_the_design_cannot_support_is_left_out_before_fitting():
    """Each scene seen in one condition only: no slope of condition by scene can be estimated."""
    from analysis.selection import choose

    data = _slope_study([11, 2])
    data = data[data["scene"].map(lambda s: int(s[1:]) % 3) == data["condition"].cat.codes].copy()
    chosen = choose(data, "log_time", "gaussian")
    scene = next(step for step in chosen.steps if step.structure == "slopes of condition by scene")
    assert scene.decision.startswith("left out before fitting") and "never varies within a level of scene" in \
        scene.decision
    assert not any("by scene" in step.structure for step in chosen.steps if step.formula)


def test_a_structure_that_cannot_be_made_is_simplified_and_the_measure_still_tested():
    """Conditions named as a formula cannot spell ("c(d)", "a + b"): an uncorrelated slope's term cannot be written,
    so that step fails, says why, and the rule goes on to a structure it can fit; the measure is never lost."""
    from analysis.selection import choose

    data = _slope_study([11, 1])
    odd = ["none", "c(d)", "a + b"]
    data["condition"] = pd.Categorical(data["condition"].map(dict(zip(LEVELS, odd, strict=True))), odd)
    chosen = choose(data, "log_time", "gaussian")
    failed = [step for step in chosen.steps if any(m.startswith("the fit failed: ") for m in step.messages)]
    assert failed and all(step.structure.startswith("uncorrelated") for step in failed)
    assert all("leave out the slope" in step.decision for step in failed)
    assert chosen.kept is not None and chosen.comparison.lrt.df == 2
    assert chosen.steps[-1].decision.startswith("kept")


def test_the_report_leaves_a_counts_slopes_out_before_fitting_and_says_why():
    from analysis.selection import COUNT_SLOPES, choose

    chosen = choose(_slope_study([11, 1]), "n_queries", "poisson")
    assert [s.structure for s in chosen.steps] == ["slopes of condition by participant", "slopes of condition by scene",
                                                   "intercepts only"]
    assert all(s.decision == f"left out before fitting: {COUNT_SLOPES}" for s in chosen.steps[:2])
    assert chosen.comparison is chosen.intercepts and chosen.kept.name() == "intercepts only"


def test_a_count_starts_maximal_and_is_simplified_by_the_same_rule():
    """A Poisson measure gets the same rule as a Gaussian one: maximal first, then by singularity and convergence;
    its test runs under the structure kept, with the same random effects in the null model."""
    from analysis.selection import choose

    for seed in ([11, 1], [11, 4]):
        chosen = choose(_slope_study(seed), "n_queries", "poisson", count_slopes=True)
        assert chosen.steps[0].structure == "correlated slopes of basic, full by participant; basic, full by scene"
        assert all(step.formula for step in chosen.steps)  # every structure fitted, none left out beforehand
        assert chosen.steps[-1].decision.startswith("kept") and chosen.comparison.full.family == "poisson"
        assert chosen.comparison.full.formula == chosen.steps[-1].formula
        random_part = [f.formula.split(" + ", 1)[1] for f in (chosen.comparison.full, chosen.comparison.null)]
        assert random_part[0] == random_part[1]
        for step in chosen.steps[:-1]:
            assert step.singular or step.messages


def test_a_table_cell_with_lme4s_line_break_or_a_formulas_pipe_stays_one_markdown_row():
    from analysis.tables import Table

    message = "Model is nearly unidentifiable: large eigenvalue ratio\n - Rescale variables?"
    text = Table("t", "T", "c", ["Formula", "Note"], [["(1 | participant)", message]]).markdown()
    assert text.splitlines()[-1] == ("| (1 \\| participant) | Model is nearly unidentifiable: large eigenvalue ratio "
                                     " - Rescale variables? |")
