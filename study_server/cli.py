"""``scenesuggest schedule …`` and ``scenesuggest study …``: study files, the study server and its data from the
command line. Registered lazily by the main command (``scenesuggest.cli``), so the engine never imports the server.
Errors (:class:`scenesuggest.errors.SceneSuggestError`) print ``Error: …`` and exit with 2 through its handler.
"""

from __future__ import annotations

import os
import shlex
import sys
from contextlib import contextmanager
from pathlib import Path

import click

from scenesuggest.console import emit
from scenesuggest.errors import SceneSuggestError

from . import create_app, upgrade_database
from .base import config
from .experimenter.export import export_to
from .studies.schedule import williams_square
from .studies.served import load_studies


@click.group()
def schedule() -> None:
    """Balanced orders for within-subject designs."""


@schedule.command("williams")
@click.argument("n", type=click.IntRange(min=1, max=26))
@click.option("--json", "as_json", is_flag=True)
def schedule_williams_cmd(n: int, as_json: bool) -> None:
    """The rows of a Williams design for N conditions (0-based condition indices)."""
    rows = williams_square(n)
    letters = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    emit({"n": n, "rows": rows}, as_json,
         "\n".join(f"row {i:>2}: " + " ".join(letters[c] for c in r) for i, r in enumerate(rows)))


@click.group()
def study() -> None:
    """Study files, the study server and its data."""


@study.command("init")
@click.argument("folder", type=click.Path(file_okay=False))
@click.option("--corpus", default="ai2thor", show_default=True, help="The scene corpus the study's priors and "
              "models come from: the built-in 'ai2thor', or 'stanford:DIR' (a copy of the Stanford Scene Database: "
              "the study gets its own library and priors, built here in a minute or two).")
@click.option("--meshes", default=None, type=click.Path(file_okay=False), help="The Stanford corpus's OBJ mesh folder "
              "(default: $SCENESUGGEST_STANFORD_MESHES, DIR/models or DIR/../stanford_models/models).")
@click.option("--title", default=None, help="The title participants see (default: from the folder's name).")
@click.option("--id", "study_id", default=None, help="The study id in URLs and exports (default: the folder's name).")
@click.option("--json", "as_json", is_flag=True)
def study_init_cmd(folder: str, corpus: str, meshes: str | None, title: str | None, study_id: str | None,
                   as_json: bool) -> None:
    """Start a new study in FOLDER (absent or empty): a study file with every key, commented, a practice and a
    target scene, and a README of the next steps. Never overwrites anything."""
    from .studies.new_study import command, init_study

    written = init_study(folder, corpus, title, study_id, meshes, say=lambda m: click.echo(m, err=True))
    study_file = Path(folder) / "study.toml"
    load_studies([study_file], check=False)  # what was written validates
    quoted = shlex.quote(str(study_file))  # the commands are pasted into a shell: a folder named $(…) stays a name
    cmd = command()
    emit({"folder": str(Path(folder).resolve()), "files": [str(p) for p in written]}, as_json,
         "\n".join([f"wrote {p}" for p in written] + [
             "", f"next: {cmd} study validate {quoted}",
             f"      SCENESUGGEST_STUDIES={quoted} {cmd} study serve",
             f"      (the steps after that are in {Path(folder) / 'README.md'})"]))


@study.command("validate")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--resources/--no-resources", default=True, help="Also check the priors file and model library.")
@click.option("--json", "as_json", is_flag=True)
def study_validate_cmd(file: str, resources: bool, as_json: bool) -> None:
    """Check a study file (keys, scenes, and optionally its priors and library); errors name the key. The
    server's own priors and library, when not built yet, are reported as what 'study prepare' will build."""
    from .studies.prepare import problems

    rt = next(iter(load_studies([Path(file)], check=False).values()))
    s = rt.study
    to_build = sorted(problems(s)) if resources and s.server_resources else []
    if resources and not s.server_resources:
        rt.check_resources()  # what a study file names must be there
    if resources and not to_build:
        rt.warm()  # and load: a damaged priors, library or engine file is named here, not when served
    warnings = _warnings(s)
    info = {"id": s.id, "hash": s.hash, "conditions": [c.id for c in s.conditions], "rows": s.n_rows,
            "trials_per_participant": len([t for t in s.plan(0) if t.kind == "trial"]), "scenes": list(s.scenes),
            "to_prepare": to_build, "warnings": warnings}
    emit(info, as_json, f"{file}: study {s.id!r} is valid — {len(s.conditions)} conditions, {s.n_rows} schedule "
                        f"rows, {info['trials_per_participant']} trials per participant" + (
                            f"; the server's {' and '.join(to_build)} for {s.corpus} are not built yet: "
                            f"'scenesuggest study prepare {file}' builds them (and 'study serve' does first)"
                            if to_build else "") + "".join(f"\nwarning: {w}" for w in warnings))


def _warnings(s) -> list[str]:
    """What a valid study file may still get wrong: a number of participants the schedule cannot balance."""
    if s.participants % s.n_rows:
        fewer, more = s.participants // s.n_rows * s.n_rows, -(-s.participants // s.n_rows) * s.n_rows
        return [f"[design] participants = {s.participants} is not a multiple of the design's {s.n_rows} schedule "
                f"rows: the rows cannot all be filled alike ({' or '.join(str(n) for n in (fewer, more) if n)} "
                "would). It is the number the dashboard plans for; the platform's places are what stop arrivals"]
    return []


@study.command("migrate")
def study_migrate_cmd() -> None:
    """Create or upgrade the database schema (DATABASE_URL, default: SQLite in the instance folder)."""
    upgrade_database(create_app({"CHECK_RESOURCES": False}))
    click.echo("database is at the newest schema revision")


def _prepare(files: list[Path]) -> list[str]:
    """Build the server's own priors and libraries that the studies of ``files`` use, where missing or stale."""
    from scenesuggest.console import progress

    from .studies.prepare import prepare

    built = []
    for rt in load_studies(files, check=False).values():
        built += [f"{rt.study.id}: {what}" for what in prepare(rt.study, progress, lambda m: click.echo(m, err=True))]
    return built


@study.command("prepare")
@click.argument("files", nargs=-1, type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True)
def study_prepare_cmd(files: tuple[str, ...], as_json: bool) -> None:
    """Build the priors and model libraries that study FILES (default: the configured studies) take from the
    server: those of studies that name only their corpus, where missing or made by other engine code."""
    built = _prepare([Path(f) for f in files] or config.study_files())
    emit({"built": built}, as_json, "built " + ", ".join(built) if built else "every study has its resources")


@study.command("serve")
@click.option("--host", default="127.0.0.1", show_default=True)
@click.option("--port", default=5000, show_default=True)
@click.option("--workers", default=2, show_default=True)
@click.option("--prepare/--no-prepare", default=True, show_default=True,
              help="First build missing priors and model libraries (see 'study prepare').")
def study_serve_cmd(host: str, port: int, workers: int, prepare: bool) -> None:
    """Prepare, migrate, then serve the configured studies with gunicorn (SCENESUGGEST_STUDIES, DATABASE_URL)."""
    if prepare:
        _prepare(config.study_files())
    app = create_app({"WARM_STUDIES": False})  # this process only migrates; the workers warm
    if app.config.get("PROXY_HOPS") and not _loopback(host):
        raise SceneSuggestError(
            f"SCENESUGGEST_PROXY_HOPS={app.config['PROXY_HOPS']} makes the app believe X-Forwarded-For, so it must "
            f"be reachable through the proxy only: bound to {host}, anyone reaching the port directly could claim "
            "any address (and dodge the arrival quota and login limits). Bind to 127.0.0.1 behind the proxy, or "
            "set SCENESUGGEST_PROXY_HOPS=0", field="--host")
    upgrade_database(app)
    for rt in app.extensions["studies"].values():  # a file that cannot be loaded stops the start here, once, named
        rt.warm()
    password_file = config.ensure_admin_password(config.instance_path())
    base = f"http://{host}:{port}"
    for rt in app.extensions["studies"].values():
        click.echo("\n".join(entry_links(app, rt.study, base)))
    click.echo(f"admin:            {base}/admin/  (password in {password_file})" if password_file else
               f"admin:            {base}/admin/  (password: the one whose hash is in "
               "SCENESUGGEST_ADMIN_PASSWORD_HASH)")
    sys.stdout.flush()
    os.environ.setdefault("SCENESUGGEST_WARM", "1")  # each worker loads the studies before its first request
    os.execv(sys.executable, gunicorn_command(workers, f"{host}:{port}"))


def gunicorn_command(workers: int, bind: str) -> list[str]:
    """How ``study serve`` runs gunicorn: with the settings of :mod:`study_server.base.gunicorn_settings` (an access log
    without secrets, no control socket; never a gunicorn.conf.py of the working directory). --timeout: a worker
    answering one request longer than this is killed; the admin's export streams a large study for longer than
    gunicorn's default 30 s (330 MB of events: about a minute)."""
    return [sys.executable, "-m", "gunicorn", "-c", "python:study_server.base.gunicorn_settings",
            "--workers", str(workers), "--timeout", "300", "--bind", bind, "--access-logfile", "-",
            "study_server:create_app()"]


def entry_links(app, study, base: str) -> list[str]:
    """What ``study serve`` prints of a study: the participants' link for its platform, and a fresh test link."""
    from .participants import pilots

    start = f"{base}/study/{study.id}/start"
    return [f"participants' link ({study.platform}): {pilots.participant_link(study, start)}",
            f"test link (a pilot, new at each start: kept out of the data; open it yourself): "
            f"{pilots.test_link(app.config['SECRET_KEY'], study, start)}"]


def _loopback(host: str) -> bool:
    import ipaddress

    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _study_app(study: str, database_url: str | None, **config_overrides):
    """The app (no resources checked) on ``database_url`` (default: the server's) with the study ``study`` names:
    a configured study's id, or a study file (then served alone); and that study's id."""
    overrides = {"CHECK_RESOURCES": False, "WARM_STUDIES": False, **config_overrides}
    if database_url:
        _existing_sqlite(database_url)
        overrides |= {"SQLALCHEMY_DATABASE_URI": database_url, "DATABASE_FROM_COMMAND_LINE": True}
    as_file = Path(study)
    if study.endswith(".toml") or as_file.is_file():
        if not as_file.is_file():
            raise SceneSuggestError("no such study file", file=study, field="--study")
        overrides["STUDY_FILES"] = [as_file]
    app = create_app(overrides)
    studies = app.extensions["studies"]
    study_id = next(iter(studies)) if "STUDY_FILES" in overrides else study
    if study_id not in studies:
        raise SceneSuggestError(
            f"no study {study!r} among the configured studies ({', '.join(studies) or 'none'}): name its study file "
            f"(--study path/to/study.toml), or set SCENESUGGEST_STUDIES to it as the server has it", field="--study")
    return app, study_id


def _existing_sqlite(url: str) -> None:
    """A SQLite database named on the command line must be there (a mistyped path would make a new, empty one)."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError, NoSuchModuleError

    try:
        parsed = make_url(url)
        parsed.get_dialect()
    except (ArgumentError, NoSuchModuleError):
        raise SceneSuggestError(f"{url!r} is not a database URL (sqlite:///FILE or postgresql+psycopg://…)",
                                field="--db") from None
    name = parsed.database or ""
    if parsed.get_backend_name() == "sqlite" and name and name != ":memory:" and not Path(name).is_file():
        raise SceneSuggestError(f"no database file {Path(name).resolve()}", field="--db")


@contextmanager
def _reading(app):
    """The app's database, read within; a database without the study tables, or one that cannot be read, is an
    error that says so (not a traceback)."""
    from sqlalchemy import inspect
    from sqlalchemy.exc import SQLAlchemyError

    from .base.extensions import db

    with app.app_context():
        where = db.engine.url.render_as_string(hide_password=True)
        try:
            if not inspect(db.engine).has_table("participants"):
                raise SceneSuggestError(f"{where} holds no study data (no participants table): name the server's "
                                        "database (DATABASE_URL, or --db)", field="--db")
            yield
        except SQLAlchemyError as e:
            raise SceneSuggestError(f"cannot read {where}: {str(e).splitlines()[0]}", field="--db") from None


@study.command("export")
@click.option("--study", "study", required=True, help="The study: its study file, or the id of a configured study "
                                                      "(SCENESUGGEST_STUDIES).")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False))
@click.option("--db", "database_url", default=None, help="Database URL (default: DATABASE_URL or the instance DB).")
@click.option("--json", "as_json", is_flag=True)
def study_export_cmd(study: str, out: str, database_url: str | None, as_json: bool) -> None:
    """Write the study's tidy CSV tables, manifest.json and data dictionary to OUT."""
    app, study_id = _study_app(study, database_url)
    with _reading(app):
        manifest = export_to(app.extensions["studies"][study_id], Path(out))
    emit(manifest, as_json, f"exported {study_id} to {out}: " + ", ".join(f"{n} {k}" for k, n in
                                                                        manifest["row_counts"].items()))


@study.command("reset")
@click.option("--study", "study", required=True, help="The study: its study file, or the id of a configured study.")
@click.option("--db", "database_url", default=None, help="Database URL (default: DATABASE_URL or the instance DB).")
@click.option("--pilots-only", is_flag=True, help="Remove only the pilots (test runs and simulated participants).")
@click.option("--force", is_flag=True, help="Also remove real participants (back the database up first).")
@click.option("--yes", is_flag=True, help="Do not ask before removing.")
@click.option("--json", "as_json", is_flag=True)
def study_reset_cmd(study: str, database_url: str | None, pilots_only: bool, force: bool, yes: bool,
                    as_json: bool) -> None:
    """Remove a study's participants and everything they left (trials, events, lists, surveys, session log):
    before launch, to start clean after pilots. Refused once real participants have arrived, unless --force;
    --pilots-only removes the pilots alone, at any time."""
    from .base.extensions import db
    from .participants import pilots

    app, study_id = _study_app(study, database_url)
    with _reading(app):
        found = pilots.counts(study_id)
        going = found["pilot"] + (0 if pilots_only else found["real"])
        try:
            pilots.check_reset(study_id, found, pilots_only, force)
        except pilots.RealParticipants as e:
            raise SceneSuggestError(e.message, field="--force") from None
        if going and not yes:
            click.confirm(f"remove {going} participant(s) of {study_id} ({found['pilot']} pilot(s)"
                          + ("" if pilots_only else f", {found['real']} real") + ") and everything they left "
                          f"from {db.engine.url.render_as_string(hide_password=True)}?", abort=True, err=True)
        removed = pilots.reset(study_id, pilots_only=pilots_only, force=force)
        db.session.commit()
    emit({"study": study_id, "removed": removed}, as_json,
         f"removed {removed['participants']} participant(s) of {study_id} "
         f"({', '.join(f'{n} {k}' for k, n in removed.items() if k != 'participants')})")


def _database_url(database_url: str | None) -> str:
    """--db (a relative SQLite path: relative to where the command runs), else what the server uses (DATABASE_URL,
    relative to the instance folder as the server takes it, else the instance folder's SQLite file)."""
    if database_url:
        return config.absolute_sqlite(database_url, Path.cwd())
    return config.absolute_sqlite(config.from_environment(config.instance_path())["SQLALCHEMY_DATABASE_URI"],
                                  config.instance_path())


@study.command("backup")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False), help="The backup file (new).")
@click.option("--db", "database_url", default=None, help="Database URL (default: DATABASE_URL or the instance DB).")
@click.option("--json", "as_json", is_flag=True)
def study_backup_cmd(out: str, database_url: str | None, as_json: bool) -> None:
    """Back up the database while the server runs: SQLite's online backup, or pg_dump's custom format."""
    from .experimenter.backup import backup

    done = backup(_database_url(database_url), out)
    emit(done, as_json, f"backed up {done['participants']} participants and {done['events']} events "
                        f"(schema {done['revision']}, {done['kind']}) to {out}: {done['file_bytes']} bytes, its "
                        f"database's SHA-256 {done['sha256'][:16]}…")


@study.command("restore")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--db", "database_url", default=None, help="Database URL (default: DATABASE_URL or the instance DB).")
@click.option("--json", "as_json", is_flag=True)
def study_restore_cmd(file: str, database_url: str | None, as_json: bool) -> None:
    """Restore a backup 'study backup' wrote into an empty database (one with no tables), as the app's role.
    Refused, naming why: a file whose digest does not match, and one holding what the migrations do not create
    (triggers, views, functions, changed tables). Sign-ins are not carried across."""
    from .experimenter.backup import restore

    done = restore(file, _database_url(database_url))
    emit(done, as_json, f"restored {done['participants']} participants and {done['events']} events (schema "
                        f"{done['revision']}; integrity {done['integrity']}); run 'scenesuggest study migrate' if "
                        "the server's code is newer than the backup")


@study.command("admin-link")
@click.option("--minutes", default=15, show_default=True, type=click.IntRange(1, 24 * 60),
              help="How long the link works (it works once).")
@click.option("--base", default="http://127.0.0.1:5000", show_default=True,
              help="The server's public address, e.g. https://study.example.org.")
@click.option("--json", "as_json", is_flag=True)
def study_admin_link_cmd(minutes: int, base: str, as_json: bool) -> None:
    """Print a one-time admin sign-in link: the operator's way in that failed logins cannot close (run it where
    the server's database is: DATABASE_URL or the instance folder)."""
    from datetime import timedelta

    from .base.security import new_admin_link

    if not base.startswith(("http://", "https://")) or any(c.isspace() for c in base):
        raise SceneSuggestError("expected the server's address, like https://study.example.org", field="--base")
    app = create_app({"CHECK_RESOURCES": False, "WARM_STUDIES": False})
    with app.app_context():
        from sqlalchemy import inspect

        from .base.extensions import db

        if not inspect(db.engine).has_table("admin_links"):
            raise SceneSuggestError(f"the database {db.engine.url.render_as_string(hide_password=True)} has no "
                                    "admin_links table: run this where the server runs, with its environment "
                                    "(DATABASE_URL), after 'scenesuggest study migrate'", field="DATABASE_URL")
        secret = new_admin_link(timedelta(minutes=minutes))
    url = f"{base.rstrip('/')}/admin/link/{secret}"
    emit({"url": url, "minutes": minutes}, as_json,
         f"{url}\nworks once, for {minutes} minutes: open it in the browser you administer from")


@study.command("deploy-files")
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Folder to write them into (new).")
@click.option("--server-name", required=True, help="The study's public host name (TLS certificate's name).")
@click.option("--app", "app_ports", multiple=True, type=int, default=(8001, 8002), show_default=True,
              help="Port of an app server on 127.0.0.1 (repeat for each).")
@click.option("--http-port", default=80, show_default=True)
@click.option("--https-port", default=443, show_default=True)
@click.option("--cert", default=None, help="TLS certificate chain (default: certbot's for the server name).")
@click.option("--key", default=None, help="Its private key (default: certbot's).")
@click.option("--user", default="scenesuggest", show_default=True, help="The system user the app servers run as.")
@click.option("--workers", default=2, show_default=True, help="gunicorn workers per app server.")
@click.option("--json", "as_json", is_flag=True)
def study_deploy_files_cmd(out: str, server_name: str, app_ports: tuple[int, ...], http_port: int, https_port: int,
                           cert: str | None, key: str | None, user: str, workers: int, as_json: bool) -> None:
    """Write nginx's site and proxy settings, the app servers' systemd unit and their environment file, filled
    in for this installation and the configured studies (see "Running a study for real" in the README)."""
    from .experimenter.deployment import Deployment, write_deploy_files

    written = write_deploy_files(out, Deployment(server_name, list(app_ports), http_port, https_port, cert=cert,
                                                 key=key, user=user, workers=workers))
    emit({"files": [str(p) for p in written]}, as_json, "\n".join(f"wrote {p}" for p in written))
