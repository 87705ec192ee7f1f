"""``report/reproduce.R``: run with Rscript on the report of a study the bots took, it prints the report's
likelihood-ratio tests and fixed effects (lme4 fitting the report's own measure files)."""

from __future__ import annotations

import subprocess

import pytest
from demostudy import make_app
from support import require_lme4

from analysis.load import read_database
from analysis.report import build_report
from simulation.run import simulate


def printed(text: str) -> tuple[dict, dict, dict]:
    """The LR tests (with the intercept-only test and the random part used), the measures not modelled and the
    fixed effects that reproduce.R printed."""
    tests, not_modelled, fixed = {}, {}, {}
    section = None
    for line in text.splitlines():
        cells = line.split()
        if line.startswith(("Likelihood-ratio tests", "Random effects", "Fixed effects")):
            section = line[0]
        elif not cells or cells[0] == "measure":
            continue
        elif section == "L" and "not modelled:" in line:
            not_modelled[cells[0]] = line.split("not modelled:", 1)[1].strip()
        elif section == "L":
            tests[cells[0]] = {"chi2": float(cells[2]), "df": int(cells[3]), "n": int(cells[4]), "p": float(cells[5]),
                               "chi2_intercepts": float(cells[6]), "p_intercepts": float(cells[7])}
        elif section == "R":
            tests[cells[0]]["random"] = line.split(None, 1)[1]
        elif section == "F":
            fixed[(cells[0], cells[1])] = (float(cells[2]), float(cells[3]))
    return tests, not_modelled, fixed


@pytest.mark.slow
def test_reproduce_r_finds_the_reports_numbers(tmp_path, demo_resources):
    rscript = require_lme4()
    app = make_app(tmp_path / "server")
    summary = simulate(6, seed=11, study="demo", app=app)
    assert summary["completed"] == 6
    folder = tmp_path / "my study" / "report"  # a path with a space, as people name folders
    report = build_report(read_database(app.config["SQLALCHEMY_DATABASE_URI"]), folder, resamples=20)
    script = folder / "reproduce.R"
    assert "Rscript reproduce.R" in (folder / "README.md").read_text()
    ran = subprocess.run([rscript, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert ran.returncode == 0, ran.stderr
    tests = same_numbers(report, ran.stdout)
    assert len(tests) >= 5  # every measure the bots vary is modelled


def same_numbers(report: dict, stdout: str) -> dict:
    """reproduce.R's output against the report: the same measures modelled and not, each under the random effects
    the report chose, with the same tests (and the intercept-only test beside), fixed effects and SEs."""
    tests, not_modelled, fixed = printed(stdout)
    ours = report["tests"]
    assert list(tests) == [m for m, t in ours.items() if not t.get("error")]  # in the report's order
    assert {m for m, t in ours.items() if t.get("error")} == set(not_modelled)
    dummies = {f"condition{c}": f".condition{k}" for k, c in enumerate(report["conditions"], 1)}
    for measure, lrt in tests.items():
        mine, chosen = ours[measure]["lrt"], ours[measure]["selection"]
        random = chosen["random"]
        for name, column in sorted(dummies.items(), key=lambda kv: -len(kv[0])):
            random = random.replace(name, column)
        assert lrt["random"] == random, measure
        assert (lrt["df"], lrt["n"]) == (mine["df"], mine["n"]), measure
        assert lrt["chi2"] == pytest.approx(mine["chi2"], rel=1e-4, abs=1e-3), measure
        assert lrt["p"] == pytest.approx(mine["p"], rel=1e-3), measure
        alone = chosen["intercepts_only"]
        assert lrt["chi2_intercepts"] == pytest.approx(alone["chi2"], rel=1e-4, abs=1e-3), measure
        assert lrt["p_intercepts"] == pytest.approx(alone["p"], rel=1e-3), measure
        for term, value in ours[measure]["fixed"].items():
            estimate, se = fixed[(measure, term)]
            assert estimate == pytest.approx(value["estimate"], abs=1e-4 * max(abs(value["estimate"]), se)), term
            if not (ours[measure]["family"] == "poisson" and ours[measure]["singular"]):  # no curvature at θ = 0
                assert se == pytest.approx(value["se"], rel=1e-4), (measure, term)
    return tests


def test_reproduce_r_fits_the_random_slopes_the_report_chose(tmp_path):
    """Synthetic participants whose speed scales every time: rotation and translation time keep random slopes
    (lme4 fits them from dummies reproduce.R makes), the other measures come down to intercepts."""
    from analysis.load import read_export
    from analysis.synthetic import write_export

    rscript = require_lme4()
    data = read_export(write_export(tmp_path / "export", participants=20, seed=3))
    report = build_report(data, tmp_path / "report", resamples=20)
    kept = {m: t["selection"]["kept"] for m, t in report["tests"].items() if t["modelled"]}
    assert kept["rotation_time"] == "uncorrelated slopes of basic by participant"
    assert kept["translation_time"] == "uncorrelated slopes of basic by scene"
    assert kept["total_time"] == "intercepts only"
    ran = subprocess.run([rscript, str(tmp_path / "report" / "reproduce.R")], capture_output=True, text=True,
                         timeout=300)
    assert ran.returncode == 0, ran.stderr
    tests = same_numbers(report, ran.stdout)
    assert tests["rotation_time"]["random"] == "(1 | participant) + (0 + .condition2 | participant) + (1 | scene)"
    text = (tmp_path / "report" / "README.md").read_text()
    assert "Would random intercepts alone have changed a conclusion?" in text
    assert "- Rotation time (s): With random intercepts only, the test of condition gives p < .001" in text


def test_ids_stay_text_in_r_as_in_the_report(tmp_path):
    """Scenes named "01", "1", "001", "NA", "TRUE" and "1e3" are six scenes to the report and to reproduce.R alike
    (R's read.csv would make numbers, a logical and a missing value of them)."""
    import pandas as pd

    from analysis.load import read_export
    from analysis.synthetic import write_export

    rscript = require_lme4()
    export = write_export(tmp_path / "export", participants=12, seed=6)
    names = {"S1": "01", "S2": "1", "S3": "001", "S4": "NA", "S5": "TRUE", "S6": "1e3"}
    trials = pd.read_csv(export / "trials.csv", keep_default_na=False)
    trials["scene"] = trials["scene"].map(lambda s: names.get(s, s))
    trials.to_csv(export / "trials.csv", index=False)
    data = read_export(export)
    assert set(data.trials["scene"]) >= set(names.values())
    report = build_report(data, tmp_path / "report", resamples=20)
    assert report["tests"]["total_time"]["groups"]["scene"] == 6
    ran = subprocess.run([rscript, str(tmp_path / "report" / "reproduce.R")], capture_output=True, text=True,
                         timeout=300)
    assert ran.returncode == 0, ran.stderr
    tests, _, fixed = printed(ran.stdout)
    for measure, lrt in tests.items():
        assert (lrt["n"], lrt["df"]) == (report["tests"][measure]["lrt"]["n"], report["tests"][measure]["lrt"]["df"])
        assert lrt["chi2"] == pytest.approx(report["tests"][measure]["lrt"]["chi2"], rel=1e-4, abs=1e-3), measure


@pytest.mark.filterwarnings("ignore:Glyph 0")  # matplotlib has no glyph for the NUL in a figure legend
def test_condition_names_r_cannot_hold_leave_the_script_out_and_say_so(tmp_path):
    """Quotes, backslashes, other scripts and long names are written as R strings; a NUL or a lone surrogate
    (which no R string holds) leaves reproduce.R unwritten, says why in the notes, and the rest of the report
    stands."""
    from analysis.errors import AnalysisError
    from analysis.load import read_export
    from analysis.reproduce import write_reproduce_r
    from analysis.synthetic import write_export
    from analysis.tables import MEASURES

    odd = ['say "hi"', "back\\slash", "ünï ☃ 条件", "x" * 10_000]
    text = write_reproduce_r(tmp_path, MEASURES, odd).read_text(encoding="utf-8")
    assert 'c("say \\"hi\\"", "back\\\\slash", "ünï ☃ 条件", "' + "x" * 10_000 + '")' in text
    for bad in ("nul\x00here", "lone\ud800surrogate"):
        with pytest.raises(AnalysisError) as info:
            write_reproduce_r(tmp_path / "bad", MEASURES, ["none", bad])
        assert info.value.where == "condition"
    data = read_export(write_export(tmp_path / "export", participants=6, seed=2))
    data.trials["condition"] = data.trials["condition"].replace("full", "full\x00")
    data.manifest.pop("design", None)
    report = build_report(data, tmp_path / "report", resamples=20)
    assert not (tmp_path / "report" / "reproduce.R").exists()
    assert any(n.startswith("reproduce.R: not written") for n in report["notes"])
    assert (tmp_path / "report" / "results.json").exists() and report["tests"]["total_time"].get("lrt")
