"""``scenesuggest study simulate`` and ``study calibrate``: simulated participants from the command line. The
main command (``scenesuggest.cli``) adds them to the ``study`` group when that group is used, so the server
never imports the simulation; in process, the simulation builds the server with its public factory."""

from __future__ import annotations

from pathlib import Path

import click

from scenesuggest.console import emit
from scenesuggest.errors import SceneSuggestError


def _app(study_id: str | None, database_url: str | None = None, migrate: bool = True):
    """The server in process (on ``database_url``, default DATABASE_URL) and the study id (default: the first
    configured study)."""
    from study_server import create_app, upgrade_database

    app = create_app({"SQLALCHEMY_DATABASE_URI": database_url, "DATABASE_FROM_COMMAND_LINE": True}
                     if database_url else None)
    if migrate:
        upgrade_database(app)
    studies = list(app.extensions["studies"])
    if study_id is None:
        study_id = studies[0]
    elif study_id not in studies:
        raise SceneSuggestError(f"no study {study_id!r} among {', '.join(studies)}", field="study")
    return app, study_id


def _study(app, study_id: str):
    from study_server.trials.offline import OfflineAnswers

    return OfflineAnswers(app, study_id).study


@click.command("simulate")
@click.option("--participants", default=20, show_default=True, type=click.IntRange(min=1))
@click.option("--seed", default=0, show_default=True)
@click.option("--url", default=None, help="A running server (its study file and secret key must be this "
                                          "environment's: the bots' entry links are signed as pilots' with it).")
@click.option("--db", "database_url", default=None,
              help="In process: the database the bots go into (default: the pilot database, "
                   "INSTANCE/pilot.sqlite3, apart from the study's own).")
@click.option("--live", is_flag=True, help="In process, into the study's own database (DATABASE_URL), as pilots: "
                                           "marked, left out of the rows' balance and the analysis.")
@click.option("--study", "study_id", default=None, help="Study id (default: the first configured study).")
@click.option("--calibration", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Behave as a calibration file says (from `study calibrate`; default: the parameters' defaults).")
@click.option("--on", "on", default=None, callback=lambda ctx, param, v: None if v is None else _on(ctx, param, v),
              help="Refuse a --calibration that was not fitted on these conditions (e.g. none,basic).")
@click.option("--mix", is_flag=True, help="Mix in reloads, second tabs, repeated arrivals, resent batches and "
                                          "drop-outs.")
@click.option("--json", "as_json", is_flag=True)
def simulate_cmd(participants: int, seed: int, url: str | None, database_url: str | None, live: bool,
                 study_id: str | None, calibration: Path | None, on: tuple[str, ...] | None, mix: bool,
                 as_json: bool) -> None:
    """Simulated participants take the whole study through its HTTP interface; their operation times follow
    the keystroke-level model applied to what the engine returns, with the behaviour of simulation.human
    (hesitation, looking round, scanning, searching, misjudged drags and turns, practice).

    Every one is a pilot (arrived through an entry link signed with the server's key and shaped for the study's
    platform), and in process they go into a database of their own unless told otherwise: a pilot never mixes
    with a study's data."""
    from study_server.participants import pilots

    from .calibrate import read
    from .participant import Behaviours
    from .run import simulate

    if url is not None and study_id is None:
        raise SceneSuggestError("name the study (--study) when simulating against --url", field="study")
    if url is not None and (database_url or live):
        raise SceneSuggestError("--db and --live are for simulating in process; --url simulates against that "
                                "server's own database", field="--url")
    if database_url and live:
        raise SceneSuggestError("choose --db or --live, not both", field="--db")
    where = None
    if url is None and not live:
        where = database_url or pilots.database_url()
    app, study_id = _app(study_id, where if url is None else "sqlite://", migrate=url is None)
    study = _study(app, study_id)
    key = app.config["SECRET_KEY"]
    if on is not None and calibration is None:
        raise SceneSuggestError("--on checks a --calibration file: name one", field="--on")
    human = read(calibration, study, on) if calibration is not None else None
    summary = simulate(participants, seed, url=url, study=study_id, app=None if url else app,
                       behaviours=Behaviours.mixed() if mix else None, human=human,
                       entry=lambda i: pilots.entry_query(key, study),
                       progress=lambda label: click.echo(label, err=True))
    summary["database"] = None if url else _masked(app.config["SQLALCHEMY_DATABASE_URI"])  # (made absolute)
    means = ", ".join(f"{c} {s:.0f} s" for c, s in summary["mean_seconds"].items())
    emit(summary, as_json, f"{summary['completed']}/{participants} participants completed {summary['trials']} "
                           f"trials, {summary['events']} events ({summary['dropped_out']} dropped out); "
                           f"mean trial time {means}"
                           + "".join(f"\nfailed: {f['participant']}: {f['error']}" for f in summary["failures"])
                           + _where_note(str(study.path), url, where is not None, summary["database"]))
    if summary["failures"]:
        raise SceneSuggestError(f"{len(summary['failures'])} simulated participant(s) could not finish")


def _masked(url: str) -> str:
    from sqlalchemy.engine import make_url

    return make_url(url).render_as_string(hide_password=True)


def _where_note(study_file: str, url: str | None, apart: bool, database: str | None) -> str:
    """Where the pilots went, and the commands that export them and clear them away (naming the study by its
    file, so that they work without the environment this command ran in)."""
    import shlex

    study = shlex.quote(study_file)
    if url is not None:
        return (f"\nthey are pilots in the server's database (left out of its balance and analysis); remove them "
                f"there with: scenesuggest study reset --study {study} --pilots-only")
    db = f" --db {shlex.quote(database)}" if apart else ""
    kept = "the pilot database, apart from the study's own" if apart else "the study's own database, as pilots"
    return (f"\nin {kept}: {database}\nexport: scenesuggest study export --study {study}{db} --out "
            f"pilot-export/\nremove: scenesuggest study reset --study {study}{db} --pilots-only")


def _on(ctx, param, value: str) -> tuple[str, ...]:
    from .paper_tables import conditions_of

    try:
        return conditions_of(value)
    except SceneSuggestError as e:
        raise click.BadParameter(e.message) from None


def _workers() -> int:
    import os

    return max(1, min(2, len(os.sched_getaffinity(0))))


@click.command("calibrate")
@click.option("-o", "--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="The file to write: the calibration (default calibration.json), or with --explain the "
                   "identifiability table as JSON (default: printed only).")
@click.option("--on", "on", default="none", show_default=True, callback=_on,
              help="The conditions to fit on, one or two of none, basic, full separated by commas; the rest are "
                   "left out, to be predicted.")
@click.option("--explain", is_flag=True, help="Instead of fitting: how far each of Table 1 and 2's cells moves, in "
                                              "every condition, when each free parameter moves (about --start's "
                                              "parameters), and so which conditions can inform which parameter.")
@click.option("--study", "study_id", default=None, help="Study id (default: the first configured study).")
@click.option("--participants", default=40, show_default=True, type=click.IntRange(min=2),
              help="Bots per evaluation (bot i plays schedule row i).")
@click.option("--seed", default=0, show_default=True, help="The bots' seed (the same for every evaluation).")
@click.option("--evaluations", default=300, show_default=True, type=click.IntRange(min=1))
@click.option("--workers", default=None, type=click.IntRange(1, 16),
              help="Processes sharing the bots of an evaluation (default: this machine's cores, at most 2).")
@click.option("--start", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Start the fit from this calibration file's parameters (default: the parameters' defaults).")
@click.option("--draws", default=0, show_default=True, type=click.IntRange(0, 100),
              help="The calibration's uncertainty: refits on the paper's cells drawn from their sampling "
                   "distributions (`study power` uses them for its intervals).")
@click.option("--draw-evaluations", default=100, show_default=True, type=click.IntRange(min=1),
              help="Evaluations of each refit (each starts from the best fit).")
@click.option("--if-stale", is_flag=True, help="Do nothing when --out was made on these conditions, this study, "
                                               "its priors, library and simulation code (and has --draws refits; "
                                               "only the missing ones are made).")
@click.option("--json", "as_json", is_flag=True)
def calibrate_cmd(out: Path | None, on: tuple[str, ...], explain: bool, study_id: str | None, participants: int,
                  seed: int, evaluations: int, workers: int | None, start: Path | None, draws: int,
                  draw_evaluations: int, if_stale: bool, as_json: bool) -> None:
    """Fit the simulated participants' free behaviour parameters to the paper's numbers (Table 1's means, the
    spread of people its intervals' widths give, and Table 2's rank shares) for the conditions --on, by rehearsing
    the study's trials of those conditions; the other conditions' numbers are never read, and a simulation with
    the result predicts them. Writes the parameters, the loss, the seed and what the fit depends on."""
    import json

    from .calibrate import Rehearsal, add_draws, explain_lines, fingerprint, fitted_on, read, stale_keys, write
    from .calibrate import explain as explain_cells
    from .calibrate import fit as fit_cells
    from .human import Human
    from .paper_tables import CONDITIONS

    app, study_id = _app(study_id)
    study = _study(app, study_id)
    out = out if out is not None or explain else Path("calibration.json")
    base = read(start) if start is not None else None
    if base is not None and not explain:
        started_on = fitted_on(json.loads(start.read_text()))  # a fold: read() checked it
        if not set(started_on) <= set(on):
            raise SceneSuggestError(f"a fit on {' + '.join(on)} cannot start from one fitted on "
                                    f"{' + '.join(started_on)}: it would carry the numbers it leaves out",
                                    file=str(start), field="--start")
    kept = None  # a fresh calibration that lacks only draws
    if if_stale and out is not None and out.is_file():
        try:
            document = json.loads(out.read_text())
        except (OSError, ValueError):
            document = None
        if not isinstance(document, dict):
            fresh = False
        elif explain:
            fresh = (document.get("explains") is True and document.get("fingerprint") == fingerprint(study)
                     and document.get("base") == (base or Human()).values()
                     and document.get("participants") == participants and document.get("seed") == seed)
        else:
            fresh = not stale_keys(document, study, on)
            made = document.get("draws") or []
            if fresh and not (isinstance(made, list) and isinstance(document.get("participants"), int)
                              and isinstance(document.get("seed"), int)
                              and isinstance(document.get("draws_seed", 0), int)):
                fresh = False  # malformed: fitted again from the start
            elif fresh and len(made) < draws:
                fresh, kept = False, document
        if fresh:
            emit({"out": str(out), "fitted": False, "loss": document.get("loss")}, as_json,
                 f"{out}: made on {' + '.join(on) if not explain else 'every condition'}, this study, its "
                 f"priors, library and simulation code; kept")
            return
    if kept is not None:  # its draws are made as its fit was: the same bots and seed
        participants, seed = kept["participants"], kept.get("draws_seed", kept["seed"])
    progress = lambda message: click.echo(message, err=True)  # noqa: E731
    with Rehearsal(app, study_id, participants, seed, CONDITIONS if explain else on,
                   workers=workers or _workers()) as rehearsal:
        if explain:
            document = {**explain_cells(rehearsal, base, progress=progress), "explains": True,
                        "fingerprint": fingerprint(study)}
        elif kept is not None:
            document = add_draws(rehearsal, kept, draws, draw_evaluations, seed, progress)
        else:
            document = fit_cells(rehearsal, evaluations, start=base, progress=progress, draws=draws,
                                 draw_evaluations=draw_evaluations, seed=seed)
    if out is not None:
        write(document, out)
    if explain:
        emit(document, as_json, "\n".join(explain_lines(document)))
        return
    measured = "; ".join(f"{c}: " + ", ".join(f"{k} {v:.3g}" for k, v in m.items())
                         for c, m in document["measured"].items())
    emit(document, as_json, f"{out}: fitted on {' + '.join(on)}, loss {document['loss']:.2f} after "
                            f"{document['evaluations']} evaluations ({document['seconds']:.0f} s); {measured}")


def _sizes(ctx, param, value: str) -> list[int]:
    try:
        sizes = sorted({int(v) for v in value.split(",") if v.strip()})
    except ValueError:
        raise click.BadParameter("expected numbers separated by commas, e.g. 10,20,40") from None
    if not sizes or sizes[0] < 2:
        raise click.BadParameter("each size must be at least 2")
    return sizes


@click.command("power")
@click.option("--calibration", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The calibration file (from `study calibrate`); its plausible parameter sets give the range.")
@click.option("--participants", "sizes", default="10,20,40,60", show_default=True, callback=_sizes,
              help="Study sizes to compute the power at.")
@click.option("--studies", default=100, show_default=True, type=click.IntRange(min=10),
              help="Resampled studies per size.")
@click.option("--pilot", default=20, show_default=True, type=click.IntRange(min=2),
              help="Simulated participants per parameter set.")
@click.option("--sets", default=3, show_default=True, type=click.IntRange(min=1),
              help="Plausible parameter sets of the calibration to use (the best fit first).")
@click.option("--study", "study_id", default=None, help="Study id (default: the first configured study).")
@click.option("--against", type=click.Path(dir_okay=False, exists=True, path_type=Path), default=None,
              help="A study file of the same study whose conditions other engines serve: the power to tell its "
                   "engine from this study's in `full`, every participant building the scenes with both.")
@click.option("--seed", default=0, show_default=True)
@click.option("--json", "as_json", is_flag=True)
def power_cmd(calibration: Path, sizes: list[int], studies: int, pilot: int, sets: int, study_id: str | None,
              against: Path | None, seed: int, as_json: bool) -> None:
    """Participants needed for 80% power on H1 (total time) and H2 (rotation time, full vs basic), or with
    --against on telling two engines apart, from pilots of the calibrated simulated participants, with the range
    over the calibration's parameter sets (its refits on drawn cells, or the sets that fit almost as well)."""
    from .calibrate import read_plausible
    from .power import study_power

    app, study_id = _app(study_id)
    study = _study(app, study_id)
    if against is not None:
        _same_study(study, against)
    humans = read_plausible(calibration, study)[:sets]
    result = study_power(study_id, humans, sizes, studies, pilot, seed,
                         progress=lambda message: click.echo(message, err=True), against=against)
    lines = [f"power at alpha = {result['alpha']} ({studies} studies per size, pilots of {pilot} simulated "
             f"participants, {len(humans)} plausible parameter set(s): best fit [range])"]
    for name, h in result["hypotheses"].items():
        cells = ", ".join(f"N={n}: {v['best']:.2f} [{v['low']:.2f}, {v['high']:.2f}]" for n, v in h["power"].items())
        need = h["needed"]
        text = "more than tested" if need["best"] is None else str(need["best"])
        rng = f"{need['low'] or '>' + str(sizes[-1])}–{need['high'] or '>' + str(sizes[-1])}"
        lines.append(f"{name}: {cells}; participants for 80% power: {text} (range {rng})")
    emit(result, as_json, "\n".join(lines))


def _same_study(study, path: Path) -> None:
    """``path`` must be a study file of ``study`` itself (its id, conditions and scenes) with other engines."""
    from study_server import create_app

    app = create_app({"SQLALCHEMY_DATABASE_URI": "sqlite://", "DATABASE_FROM_COMMAND_LINE": True,
                      "STUDY_FILES": [str(path)]})
    found = list(app.extensions["studies"])
    if found != [study.id]:
        raise SceneSuggestError(f"another study's file: its study is {', '.join(found)}, not {study.id}",
                                file=str(path), field="--against")
    other = _study(app, study.id)
    for what, mine, theirs in (("id", study.id, other.id),
                               ("conditions", [c.id for c in study.conditions], [c.id for c in other.conditions]),
                               ("scenes", sorted(study.scenes), sorted(other.scenes))):
        if mine != theirs:
            raise SceneSuggestError(f"another study's file: its {what} {theirs!r} are not {mine!r}", file=str(path),
                                    field="--against")
