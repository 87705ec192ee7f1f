"""How close the random-slope models come to lme4: on fresh random studies (tests/test_lme4_oracle.py's generator and
R script), the largest difference of each kind, as a fraction of the oracle test's tolerance for it — 1.0 would be
at the tolerance. LMM (ML and REML) and Poisson GLMM separately; models where our optimum is above lme4's (lme4's
likelihood at our parameters confirms it) are counted, not compared.

Usage: .venv/bin/python benchmarks/lme4_agreement.py [--studies 6] [--seed 0]   (prints JSON)
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import tests_path  # noqa: F401
from test_lme4_oracle import POISSON_SLOPES, ROOT, SLOPES, python_slope_fits, random_study

from analysis.mixed import lr_test


def fractions(ours, theirs: dict) -> dict[str, float]:
    """Each compared quantity's largest |ours − lme4| over the oracle's tolerance for it."""
    out = {}
    gaussian = ours.family == "gaussian"
    loglik = -theirs["REMLcrit"] / 2 if ours.reml else theirs["logLik"]
    out["loglik"] = abs(ours.loglik - loglik) / 1e-4
    ses = theirs["se"]
    for term, value in theirs["fixef"].items():
        se = (ses or theirs["se_glmer"])[term]
        out["fixed"] = max(out.get("fixed", 0), abs(ours.fixed[term] - value) / (1e-4 * max(abs(value), se)))
        if ses and (gaussian or not ours.singular):
            out["se"] = max(out.get("se", 0), abs(ours.se[term] - ses[term]) / (1e-4 * ses[term]))
    residual = theirs["varcomp"].get("residual", 0.0)
    floor = 1e-6 * residual if gaussian else 1e-4
    for name, value in theirs["varcomp"].items():
        if ":cor(" in name:
            continue
        out["variance"] = max(out.get("variance", 0), abs(ours.variance[name] - value) / max(1e-3 * abs(value), floor))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--studies", type=int, default=6)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rscript = shutil.which("Rscript")
    if rscript is None:
        raise SystemExit("Rscript is not installed (Debian: apt-get install r-cran-lme4 r-cran-jsonlite)")
    worst: dict[str, dict[str, float]] = {"lmm": {}, "glmm": {}}
    counts = {"models": 0, "above_lme4": 0}
    with tempfile.TemporaryDirectory() as tmp:
        for study in range(args.studies):
            data, _ = random_study(np.random.default_rng([args.seed, 100 + study]), slopes=True)
            csv, out = Path(tmp) / f"s{study}.csv", Path(tmp) / f"s{study}.json"
            data.to_csv(csv, index=False)
            subprocess.run([rscript, str(ROOT / "tests" / "lme4_oracle.R"), str(csv), str(out), "slopes", "poisson"],
                           check=True, capture_output=True)
            lme4 = json.loads(out.read_text())
            ours, _ = python_slope_fits(data)
            for name, fitted in ours.items():
                counts["models"] += 1
                theirs = lme4[name]
                if fitted.loglik > (-theirs["REMLcrit"] / 2 if fitted.reml else theirs["logLik"]) + 1e-4:
                    counts["above_lme4"] += 1
                    continue
                kind = "lmm" if fitted.family == "gaussian" else "glmm"
                for key, value in fractions(fitted, theirs).items():
                    worst[kind][key] = max(worst[kind].get(key, 0.0), value)
            for name in [f"time_{s}" for s in SLOPES] + [f"queries_{s}" for s in POISSON_SLOPES]:
                test = lr_test(ours[f"{name}_null"], ours[name])
                chi2 = max(0.0, 2 * (lme4[name]["logLik"] - lme4[f"{name}_null"]["logLik"]))
                kind = "lmm" if name.startswith("time") else "glmm"
                fraction = abs(test.chi2 - chi2) / max(1e-4 * chi2, 1e-3)
                # a test where either model is above lme4's optimum is lme4's shortfall, counted above
                if math.isfinite(fraction) and all(ours[m].loglik <= lme4[m]["logLik"] + 1e-4
                                                   for m in (name, f"{name}_null")):
                    worst[kind]["lr_chi2"] = max(worst[kind].get("lr_chi2", 0.0), fraction)
    print(json.dumps({"benchmark": "lme4-agreement-random-slopes", "studies": args.studies, "seed": args.seed,
                      **counts, "worst_fraction_of_tolerance": {k: {q: round(v, 3) for q, v in w.items()}
                                                                for k, w in worst.items()}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
