"""``scenesuggest study simulate`` and ``study calibrate``: simulated participants from the command line. The
main command (``scenesuggest.cli``) adds them to the ``study`` group when that group is used, so the server
never imports the simulation; in process, the simulation builds the server with its public factory."""

from __future__ import annotations

from pathlib import Path

import click

from scenesuggest.cli import emit
from scenesuggest.errors import SceneSuggestError


def _app(study_id: str | None):
    """The server in process (on DATABASE_URL) and the study id (default: the first configured study)."""
    from study_server import create_app, upgrade_database

    app = create_app()
    upgrade_database(app)
    studies = list(app.extensions["studies"])
    if study_id is None:
        study_id = studies[0]
    elif study_id not in studies:
        raise SceneSuggestError(f"no study {study_id!r} among {', '.join(studies)}", field="study")
    return app, study_id


def _study(app, study_id: str):
    from study_server.studies import runtime

    with app.test_request_context():
        return runtime(study_id).study


@click.command("simulate")
@click.option("--participants", default=20, show_default=True, type=click.IntRange(min=1))
@click.option("--seed", default=0, show_default=True)
@click.option("--url", default=None, help="A running server (default: in process, on DATABASE_URL).")
@click.option("--study", "study_id", default=None, help="Study id (default: the first configured study).")
@click.option("--calibration", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Behave as a calibration file says (from `study calibrate`; default: the parameters' defaults).")
@click.option("--mix", is_flag=True, help="Mix in reloads, second tabs, repeated arrivals, resent batches and "
                                          "drop-outs.")
@click.option("--json", "as_json", is_flag=True)
def simulate_cmd(participants: int, seed: int, url: str | None, study_id: str | None, calibration: Path | None,
                 mix: bool, as_json: bool) -> None:
    """Simulated participants take the whole study through its HTTP interface; their operation times follow
    the keystroke-level model applied to what the engine returns, with the behaviour of simulation.human
    (hesitation, looking round, scanning, searching, misjudged drags and turns, practice)."""
    from .calibrate import read
    from .participant import Behaviours
    from .run import simulate

    app = None
    if url is None:
        app, study_id = _app(study_id)
    elif study_id is None:
        raise SceneSuggestError("name the study (--study) when simulating against --url", field="study")
    human = None
    if calibration is not None:
        human = read(calibration, _study(app, study_id) if app is not None else None)
    summary = simulate(participants, seed, url=url, study=study_id, app=app,
                       behaviours=Behaviours.mixed() if mix else None, human=human,
                       progress=lambda label: click.echo(label, err=True))
    means = ", ".join(f"{c} {s:.0f} s" for c, s in summary["mean_seconds"].items())
    emit(summary, as_json, f"{summary['completed']}/{participants} participants completed {summary['trials']} "
                           f"trials, {summary['events']} events ({summary['dropped_out']} dropped out); "
                           f"mean trial time {means}"
                           + "".join(f"\nfailed: {f['participant']}: {f['error']}" for f in summary["failures"]))
    if summary["failures"]:
        raise SceneSuggestError(f"{len(summary['failures'])} simulated participant(s) could not finish")


@click.command("calibrate")
@click.option("-o", "--out", type=click.Path(dir_okay=False, path_type=Path), default=Path("calibration.json"),
              show_default=True, help="The calibration file to write.")
@click.option("--study", "study_id", default=None, help="Study id (default: the first configured study).")
@click.option("--participants", default=40, show_default=True, type=click.IntRange(min=2),
              help="Bots per evaluation (bot i plays schedule row i).")
@click.option("--seed", default=0, show_default=True, help="The bots' seed (the same for every evaluation).")
@click.option("--evaluations", default=300, show_default=True, type=click.IntRange(min=1))
@click.option("--if-stale", is_flag=True, help="Do nothing when --out was fitted on this study, its priors, "
                                               "library and simulation code.")
@click.option("--json", "as_json", is_flag=True)
def calibrate_cmd(out: Path, study_id: str | None, participants: int, seed: int, evaluations: int, if_stale: bool,
                  as_json: bool) -> None:
    """Fit the simulated participants' free behaviour parameters to the paper's `none` condition (Table 1's
    means and Table 2's rank shares; never the other conditions' numbers) by rehearsing the study's `none`
    trials; writes the parameters, the loss, the seed and what the fit depends on."""
    import json

    from .calibrate import Rehearsal, fit, stale_keys, write

    app, study_id = _app(study_id)
    if if_stale and out.is_file():
        try:
            document = json.loads(out.read_text())
        except (OSError, ValueError):
            document = None
        if isinstance(document, dict) and not stale_keys(document, _study(app, study_id)):
            emit({"out": str(out), "fitted": False, "loss": document.get("loss")}, as_json,
                 f"{out}: fitted on this study, its priors, library and simulation code; kept")
            return
    rehearsal = Rehearsal(app, study_id, participants, seed)
    document = fit(rehearsal, evaluations, progress=lambda message: click.echo(message, err=True))
    write(document, out)
    measured = ", ".join(f"{k} {v:.3g}" for k, v in document["measured_none"].items())
    emit(document, as_json, f"{out}: loss {document['loss']:.2f} after {document['evaluations']} evaluations "
                            f"({document['seconds']:.0f} s); none: {measured}")
