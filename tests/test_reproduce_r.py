"""``report/reproduce.R``: run with Rscript on the report of a study the bots took, it prints the report's
likelihood-ratio tests and fixed effects (lme4 fitting the report's own measure files)."""

from __future__ import annotations

import subprocess

import pytest
from conftest import make_app, require_lme4

from analysis.load import read_database
from analysis.report import build_report
from simulation.run import simulate


def printed(text: str) -> tuple[dict, dict, dict]:
    """The LR tests, the measures not modelled and the fixed effects that reproduce.R printed."""
    tests, not_modelled, fixed = {}, {}, {}
    section = None
    for line in text.splitlines():
        cells = line.split()
        if line.startswith("Likelihood-ratio tests") or line.startswith("Fixed effects"):
            section = line[0]
        elif not cells or cells[0] == "measure":
            continue
        elif section == "L" and "not modelled:" in line:
            not_modelled[cells[0]] = line.split("not modelled:", 1)[1].strip()
        elif section == "L":
            tests[cells[0]] = {"chi2": float(cells[2]), "df": int(cells[3]), "n": int(cells[4]), "p": float(cells[5])}
        elif section == "F":
            fixed[(cells[0], cells[1])] = (float(cells[2]), float(cells[3]))
    return tests, not_modelled, fixed


def test_reproduce_r_finds_the_reports_numbers(tmp_path, demo_resources):
    rscript = require_lme4()
    app = make_app(tmp_path / "server")
    summary = simulate(6, seed=11, study="demo", app=app)
    assert summary["completed"] == 6
    report = build_report(read_database(app.config["SQLALCHEMY_DATABASE_URI"]), tmp_path / "report", resamples=20)
    script = tmp_path / "report" / "reproduce.R"
    assert "Rscript reproduce.R" in (tmp_path / "report" / "README.md").read_text()
    ran = subprocess.run([rscript, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert ran.returncode == 0, ran.stderr
    tests, not_modelled, fixed = printed(ran.stdout)
    ours = report["tests"]
    assert list(tests) == [m for m, t in ours.items() if not t.get("error")]  # in the report's order
    assert {m for m, t in ours.items() if t.get("error")} == set(not_modelled)
    assert len(tests) >= 5  # every measure the bots vary is modelled
    for measure, lrt in tests.items():
        mine = ours[measure]["lrt"]
        assert (lrt["df"], lrt["n"]) == (mine["df"], mine["n"]), measure
        assert lrt["chi2"] == pytest.approx(mine["chi2"], rel=1e-4, abs=1e-3), measure
        assert lrt["p"] == pytest.approx(mine["p"], rel=1e-3), measure
        for term, value in ours[measure]["fixed"].items():
            estimate, se = fixed[(measure, term)]
            assert estimate == pytest.approx(value["estimate"], abs=1e-4 * max(abs(value["estimate"]), se)), term
            if not (ours[measure]["family"] == "poisson" and ours[measure]["singular"]):  # no curvature at θ = 0
                assert se == pytest.approx(value["se"], rel=1e-4), (measure, term)
