"""The demo study in process, for the benchmarks and the tests: the study server as a Flask app on a fresh
database (driven by its test client), and a participant walked from the entry link to the first trial."""

from __future__ import annotations

import contextlib
from collections import Counter
from pathlib import Path

from serverproc import DEMO_STUDY

#: A participant's answers to the demo study's forms (demographics) on the way to the first trial.
DEMOGRAPHICS = {"age": "30", "experience_3d": "Never", "pointing_device": "Mouse"}


def play_empty_trial(transport, boot: dict, seq: int, page_id: str, t0_ms: float, duration_ms: float) -> int:
    """The trial of a trial page's ``boot`` played with nothing placed over ``transport``: its trial_start and
    trial_done events (seqs ``seq`` and ``seq`` + 1, at ``t0_ms`` and ``duration_ms`` later, ms since the epoch)
    posted from page ``page_id``, then the trial finished; returns the next seq. AssertionError unless both are
    acknowledged (200)."""
    t, auth = boot["trial"], {"Authorization": f"Bearer {boot['token']}"}
    events = [{"seq": seq, "t": t0_ms + seq, "type": "trial_start", "trial": t["index"],
               "payload": {"scene": t["scene"], "condition": t["condition"]}},
              {"seq": seq + 1, "t": t0_ms + seq + duration_ms, "type": "trial_done", "trial": t["index"],
               "payload": {"objects": 0}}]
    assert transport.post("/api/events", json_body={"page_id": page_id, "events": events}, headers=auth).status == 200
    assert transport.post("/api/trial/done", json_body={"trial": t["index"]}, headers=auth).status == 200
    return seq + 2


def make_app(folder: Path, database_url: str | None = None, studies=None, **config):
    """The study server in process serving ``studies`` (study files; default the demo study), its instance folder
    ``folder``/instance, on ``database_url`` (default: the SQLite file ``folder``/study.sqlite3) with the schema
    migrated to the newest revision. ``config`` overrides the rest: a test set-up (fixed secret key, errors not
    hidden, the studies loaded when first asked for)."""
    from study_server import create_app, upgrade_database

    app = create_app({
        "INSTANCE_PATH": str(folder / "instance"),
        "SQLALCHEMY_DATABASE_URI": database_url or f"sqlite:///{folder / 'study.sqlite3'}",
        "STUDY_FILES": studies or [DEMO_STUDY], "SECRET_KEY": "test-secret", "TESTING": True,
        "WARM_STUDIES": False, **config})
    upgrade_database(app)
    return app


def to_first_trial(transport, pid: str, study: str = "demo"):
    """Participant ``pid`` of ``study`` from the entry link to the first trial over ``transport`` (a
    :mod:`simulation.transport`), answering with :data:`DEMOGRAPHICS`; returns the trial page
    (:class:`simulation.page.Page`: its ``boot`` holds the session token and the trial). RuntimeError when the
    walk stops before it."""
    from simulation.walker import Walker

    page = Walker(transport, study).to_first_trial({"pid": pid}, lambda _: DEMOGRAPHICS)
    if page.step != "trial":
        raise RuntimeError(f"{pid} could not reach the trials (stopped at {page.step!r})")
    return page


def rows_balance(rows_of_completed, study) -> tuple[dict[int, int], bool]:
    """Completed participants per schedule row of ``study`` (loaded: :func:`study_server.studies.study_file.load_study`;
    every row, an empty one counting as none) and whether they are balanced: no two rows differ by more than one
    participant, and someone completed."""
    rows = Counter({r: 0 for r in range(study.n_rows)})
    rows.update(rows_of_completed)
    return dict(sorted(rows.items())), max(rows.values()) - min(rows.values()) <= 1 and rows.total() > 0


def copy_demo_study(tmp: Path) -> Path:
    """The demo study copied into ``tmp``/demo (its targets may then be written), its resources still the
    server's own; returns the copy's study file."""
    import shutil

    folder = tmp / "demo"
    shutil.copytree(DEMO_STUDY.parent, folder)
    return folder / "study.toml"


@contextlib.contextmanager
def gunicorn(tmp: Path, workers: int = 2):
    """The study server as `make serve` runs it (gunicorn, the demo study) on a fresh SQLite database in ``tmp``
    and a free loopback port; yields (base URL, database path)."""
    from serverproc import StudyServer

    database = tmp / "study.sqlite3"
    make_app(tmp, f"sqlite:///{database}")  # migrated here, before the workers start
    with StudyServer(tmp / "instance", f"sqlite:///{database}", workers, migrate=False) as server:
        yield server.base, database
