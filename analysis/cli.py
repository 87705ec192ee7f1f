"""``scenesuggest analyze …``: the report, mixed models and bootstrap intervals from the command line.

Errors in the input (:class:`AnalysisError`) print ``Error: WHERE: message`` and exit with 2, through the main
command's handler; ``--json`` prints one JSON document.
"""

from __future__ import annotations

import time
from pathlib import Path

import click
import pandas as pd

from .errors import AnalysisError
from .jsonout import dumps


def _emit(data: dict, as_json: bool, human: str) -> None:
    click.echo(dumps(data) if as_json else human)


def _read_csv(path: str) -> pd.DataFrame:
    try:
        return pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise AnalysisError(f"cannot be read as CSV ({e})", path) from None


@click.group()
def analyze() -> None:
    """Analyse a study: the report, mixed models, bootstrap intervals."""


@analyze.command("report")
@click.option("--export", "export_dir", type=click.Path(file_okay=False), help="Export folder (study export).")
@click.option("--db", "db_url", help="Database URL of the study server (sqlite:///…, postgresql+psycopg://…).")
@click.option("--study", default=None, help="Study id when the database holds several.")
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Folder for the report.")
@click.option("--resamples", default=1000, show_default=True, type=click.IntRange(min=10))
@click.option("--seed", default=0, show_default=True)
@click.option("--unit", type=click.Choice(["trial", "participant"]), default="trial", show_default=True,
              help="What the bootstrap resamples.")
@click.option("--completed-only", is_flag=True, help="Analyse only participants who finished the study.")
@click.option("--include-pilots", is_flag=True, help="Analyse pilots (test runs, simulated participants) with the "
              "others (by default they are left out, unless the data hold nobody else).")
@click.option("--json", "as_json", is_flag=True)
def report_cmd(export_dir, db_url, study, out, resamples, seed, unit, completed_only, include_pilots,
               as_json) -> None:
    """Every table and figure of a study, with a README stating design, N, exclusions, origin and seed."""
    from .load import read_study
    from .report import build_report

    start = time.perf_counter()

    def progress(label: str) -> None:
        click.echo(f"[{time.perf_counter() - start:5.1f} s] {label}", err=True)

    data = read_study(export_dir, db_url, study)
    summary = build_report(data, out, resamples=resamples, seed=seed, unit=unit, completed_only=completed_only,
                           include_pilots=include_pilots, progress=progress)
    readme = Path(out) / "README.md"
    _emit({"out": str(out), "readme": str(readme), "notes": summary["notes"],
           "participants": summary["participants"], "trials": summary["trials"]}, as_json,
          f"report written to {readme}" + "".join(f"\nnote: {n}" for n in summary["notes"]))


@analyze.command("lmm")
@click.argument("csv_file", metavar="CSV", type=click.Path(dir_okay=False))
@click.option("--response", required=True, help="Column to model.")
@click.option("--fixed", required=True, help="Fixed effect column (tested by a likelihood-ratio test).")
@click.option("--random", "random", required=True, multiple=True,
              help="A random-effects term (repeat for crossed factors): G, a random intercept per level of column G; "
                   "X|G adds correlated slopes of X (a number or a factor: lme4's (1 + X | G)); X||G the same "
                   "uncorrelated; 0 + X|G slopes without the intercept.")
@click.option("--family", type=click.Choice(["gaussian", "poisson"]), default="gaussian", show_default=True)
@click.option("--reference", default=None, help="Reference level of --fixed (default: its first level).")
@click.option("--reml", is_flag=True, help="Report the REML fit as well (the test always uses ML).")
@click.option("--json", "as_json", is_flag=True)
def lmm_cmd(csv_file, response, fixed, random, family, reference, reml, as_json) -> None:
    """A mixed model with and without the fixed effect, and their likelihood-ratio test (as lme4 REML = FALSE,
    glmer Laplace)."""
    from .design import build_design
    from .mixed import compare, fit

    data = _read_csv(csv_file)
    design = build_design(data, response, [fixed], list(random), reference)
    result = compare(design, fixed, family)
    f, t = result.full, result.lrt
    out = {"nobs": f.nobs, "loglik": f.loglik, "formula": f.formula, "family": family, "dropped_rows": f.dropped,
           "fixed": {k: {"estimate": v, "se": f.se[k]} for k, v in f.fixed.items()}, "variance": f.variance,
           "lrt": {"chi2": t.chi2, "df": t.df, "p": t.p, "null_loglik": t.null_loglik}, "singular": f.singular,
           "messages": list(f.messages)}
    if reml and family == "gaussian":
        r = fit(design, reml=True)
        out["reml"] = {"reml_criterion": -2 * r.loglik, "variance": r.variance,
                       "fixed": {k: {"estimate": v, "se": r.se[k]} for k, v in r.fixed.items()}}
    lines = [f"{f.formula}  ({family}, N = {f.nobs}" + (f", {f.dropped} rows with missing values dropped"
                                                        if f.dropped else "") + ")",
             f"log-likelihood {f.loglik:.4f}", ""]
    w = max(len(k) for k in [*f.fixed, *f.variance])
    lines += [f"  {'fixed effects':<{w}} {'estimate':>10} {'SE':>9}"]
    lines += [f"  {k:<{w}} {v:>10.4g} {f.se[k]:>9.4g}" for k, v in f.fixed.items()]
    lines += ["", "  variance components"] + [f"  {k:<{w}} {v:>10.4g}" for k, v in f.variance.items()]
    lines += ["", f"LR test of {fixed}: {t.text()}"] + [f"note: {m}" for m in f.messages]
    _emit(out, as_json, "\n".join(lines))


@analyze.command("bootstrap")
@click.argument("csv_file", metavar="CSV", type=click.Path(dir_okay=False))
@click.option("--value", required=True, help="Column whose mean is estimated.")
@click.option("--by", required=True, help="Column whose levels get one interval each.")
@click.option("--unit", type=click.Choice(["trial", "participant"]), default="trial", show_default=True,
              help="Resample rows of each trial together, or all rows of each participant.")
@click.option("--resamples", default=1000, show_default=True, type=click.IntRange(min=10))
@click.option("--seed", default=0, show_default=True)
@click.option("--json", "as_json", is_flag=True)
def bootstrap_cmd(csv_file, value, by, unit, resamples, seed, as_json) -> None:
    """Means per level with 95% percentile bootstrap intervals (seeded)."""
    from .bootstrap import bootstrap_by

    result = bootstrap_by(_read_csv(csv_file), value, by, None, unit, resamples, seed)
    out = {"by": {k: v.to_dict() for k, v in result.items()}, "resamples": resamples, "unit": unit, "seed": seed}
    width = max((len(k) for k in result), default=0)
    human = "\n".join(f"{k:<{width}}  {v.text(4)}  (n = {v.n})" for k, v in result.items())
    _emit(out, as_json, f"mean of {value} by {by}, 95% interval from {resamples} resamples of {unit}s:\n{human}")



def _sizes(ctx, param, value: str) -> list[int]:
    try:
        sizes = [int(v) for v in value.split(",") if v.strip()]
    except ValueError:
        raise click.BadParameter("expected numbers separated by commas, e.g. 10,20,40") from None
    if not sizes or min(sizes) < 2:
        raise click.BadParameter("each size must be at least 2")
    return sizes


@analyze.command("power")
@click.option("--export", "export_dir", type=click.Path(file_okay=False), help="Pilot export folder.")
@click.option("--db", "db_url", help="Pilot database URL.")
@click.option("--study", default=None, help="Study id when the database holds several.")
@click.option("--participants", "sizes", required=True, callback=_sizes, help="Study sizes, e.g. 10,20,40.")
@click.option("--studies", default=100, show_default=True, type=click.IntRange(min=1),
              help="Simulated studies per size.")
@click.option("--alpha", default=0.05, show_default=True, type=click.FloatRange(0, 1, min_open=True,
                                                                                    max_open=True))
@click.option("--seed", default=0, show_default=True)
@click.option("--json", "as_json", is_flag=True)
def power_cmd(export_dir, db_url, study, sizes, studies, alpha, seed, as_json) -> None:
    """Power of every LR test for each study size, from repeated studies that resample the pilot's
    participants (a real pilot, or `scenesuggest study simulate` then `study export`)."""
    from .load import read_study
    from .power import power
    from .report import select

    trials, picks, _, conditions, _ = select(read_study(export_dir, db_url, study))
    result = power(trials, picks, conditions, sizes, studies, seed, alpha,
                   progress=lambda label: click.echo(label, err=True))
    names = list(next(iter(result["power"].values())))
    header = "N".rjust(5) + "".join(n[:14].rjust(16) for n in names)
    rows = [str(n).rjust(5) + "".join(f"{v:16.2f}" for v in result["power"][str(n)].values()) for n in sizes]
    _emit(result, as_json, f"power at alpha = {alpha} from {studies} studies per size "
                           f"(pilot: {result['pilot_participants']} participants)\n" + "\n".join([header, *rows]))
