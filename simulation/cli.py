"""``scenesuggest study simulate``: simulated participants from the command line. The main command
(``scenesuggest.cli``) adds it to the ``study`` group when that group is used, so the server never imports the
simulation; in process, the simulation builds the server with its public factory."""

from __future__ import annotations

import click

from scenesuggest.cli import emit
from scenesuggest.errors import SceneSuggestError


@click.command("simulate")
@click.option("--participants", default=20, show_default=True, type=click.IntRange(min=1))
@click.option("--seed", default=0, show_default=True)
@click.option("--url", default=None, help="A running server (default: in process, on DATABASE_URL).")
@click.option("--study", "study_id", default=None, help="Study id (default: the first configured study).")
@click.option("--mix", is_flag=True, help="Mix in reloads, second tabs, repeated arrivals, resent batches and "
                                          "drop-outs.")
@click.option("--json", "as_json", is_flag=True)
def simulate_cmd(participants: int, seed: int, url: str | None, study_id: str | None, mix: bool,
                 as_json: bool) -> None:
    """Simulated participants take the whole study through its HTTP interface; their operation times follow
    the keystroke-level model applied to what the engine returns."""
    from .participant import Behaviours
    from .run import simulate

    app = None
    if url is None:
        from study_server import create_app, upgrade_database

        app = create_app()
        upgrade_database(app)
        studies = list(app.extensions["studies"])
        if study_id is None:
            study_id = studies[0]
        elif study_id not in studies:
            raise SceneSuggestError(f"no study {study_id!r} among {', '.join(studies)}", field="study")
    elif study_id is None:
        raise SceneSuggestError("name the study (--study) when simulating against --url", field="study")
    summary = simulate(participants, seed, url=url, study=study_id, app=app,
                       behaviours=Behaviours.mixed() if mix else None,
                       progress=lambda label: click.echo(label, err=True))
    means = ", ".join(f"{c} {s:.0f} s" for c, s in summary["mean_seconds"].items())
    emit(summary, as_json, f"{summary['completed']}/{participants} participants completed {summary['trials']} "
                           f"trials, {summary['events']} events ({summary['dropped_out']} dropped out); "
                           f"mean trial time {means}"
                           + "".join(f"\nfailed: {f['participant']}: {f['error']}" for f in summary["failures"]))
    if summary["failures"]:
        raise SceneSuggestError(f"{len(summary['failures'])} simulated participant(s) could not finish")
