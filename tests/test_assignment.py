"""Assignment to schedule rows: at consent, least-filled first, atomic under concurrent arrivals (threads,
processes, gunicorn workers), on SQLite and on PostgreSQL; one session per platform id; arrivals that have not
consented hold no row."""

import multiprocessing
import signal
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta

import pytest
from demostudy import DEMO_STUDY, make_app

from simulation.transport import FlowError, HttpTransport
from simulation.walker import Walker
from study_server.base.extensions import db
from study_server.base.models import Participant, Trial, utcnow
from study_server.participants.assignment import arrive, assign, row_counts


def study_of(app):
    return app.extensions["studies"]["demo"].study


def enrol(study, pid):
    """Arrival and consent: the participant with its row."""
    p, created = arrive(study, "link", pid)
    assign(study, p)
    return p, created


def test_arrivals_without_consent_hold_no_row_and_have_no_trials(app):
    with app.app_context():
        study = study_of(app)
        visitors = [arrive(study, "link", f"v{i}")[0] for i in range(8)]
        assert {p.row for p in visitors} == {-1} and db.session.query(Trial).count() == 0
        assert row_counts(study, utcnow()) == [0] * 6
        p, _ = enrol(study, "w0")
        assert p.row == 0 and db.session.query(Trial).filter_by(participant_id=p.id).count() == 10
        assert assign(study, p) == 0 and db.session.query(Trial).filter_by(participant_id=p.id).count() == 10


def test_least_filled_row_and_one_session_per_platform_id(app):
    with app.app_context():
        study = study_of(app)
        rows = [enrol(study, f"w{i}")[0].row for i in range(12)]
        assert sorted(Counter(rows).values()) == [2] * 6 and rows[:6] == [0, 1, 2, 3, 4, 5]
        again, created = enrol(study, "w3")
        assert not created and again.row == rows[3]
        assert db.session.query(Participant).count() == 12
        trials = db.session.query(Trial).filter_by(participant_id=again.id).order_by(Trial.position).all()
        assert [t.index for t in trials] == list(range(-1, 9))


def test_stale_returned_and_excluded_sessions_free_their_row(app):
    with app.app_context():
        study = study_of(app)
        people = [enrol(study, f"w{i}")[0] for i in range(6)]
        people[2].last_seen_at = utcnow() - timedelta(minutes=study.stale_after_minutes + 1)
        people[4].status = "excluded"
        people[5].status = "completed"
        people[0].status = "returned"
        db.session.commit()
        counts = row_counts(study, utcnow())
        assert counts == [0, 1, 0, 1, 0, 1]
        assert enrol(study, "new1")[0].row == 0
        assert enrol(study, "new2")[0].row == 2


def concurrent_threads(app, pids):
    def one(pid):
        with app.app_context():
            p, _ = enrol(study_of(app), pid)
            return pid, p.id, p.row
    with ThreadPoolExecutor(max_workers=16) as pool:
        return list(pool.map(one, pids))


def check_balanced(app, results, n_unique):
    by_pid = {}
    for pid, participant_id, _ in results:
        assert by_pid.setdefault(pid, participant_id) == participant_id  # one session per platform id
    with app.app_context():
        people = db.session.query(Participant).all()
        assert len(people) == n_unique
        counts = Counter(p.row for p in people)
        assert max(counts.values()) - min(counts.values()) <= 1 and len(counts) == 6


def test_concurrent_arrivals_in_threads_on_sqlite(app):
    pids = [f"t{i}" for i in range(48)] + ["same"] * 12
    check_balanced(app, concurrent_threads(app, pids), 49)


def test_concurrent_arrivals_in_threads_on_postgresql(tmp_path, postgres_db, demo_resources):
    app = make_app(tmp_path, postgres_db)
    pids = [f"t{i}" for i in range(48)] + ["same"] * 12
    check_balanced(app, concurrent_threads(app, pids), 49)


def test_concurrent_arrivals_in_processes(tmp_path, backend_url, demo_resources):
    url = backend_url
    app = make_app(tmp_path, url)
    jobs = [(url, str(tmp_path / "instance"), str(DEMO_STUDY), [f"p{k}-{i}" for i in range(10)] + ["shared"])
            for k in range(4)]
    with multiprocessing.get_context("spawn").Pool(4) as pool:
        results = [r for chunk in pool.map(__import__("workers").arrive_many, jobs) for r in chunk]
    check_balanced(app, results, 41)


@pytest.fixture
def gunicorn_server(tmp_path, request, demo_resources):
    """`make serve`'s server (gunicorn, 3 workers) on a fresh database; yields (base URL, app for queries)."""
    def start(database_url):
        from serverproc import StudyServer

        app = make_app(tmp_path, database_url)  # migrates before the workers start
        server = StudyServer(tmp_path / "instance", database_url, workers=3, migrate=False)
        request.addfinalizer(lambda: server.kill(signal.SIGTERM))
        server.start().wait_ready(timeout_s=10)
        return server.base, app
    return start


def test_concurrent_arrivals_over_http_with_several_gunicorn_workers(tmp_path, backend_url, gunicorn_server):
    url = backend_url
    base, app = gunicorn_server(url)

    def one(pid):  # each a browser of its own: the entry link, the device check, consent
        walker = Walker(HttpTransport(base), "demo")
        try:
            page = walker.enter({"pid": pid})
        except FlowError as e:  # 409: the same id is already open in another browser
            assert e.status == 409, e
            return pid
        assert walker.walk(lambda _: {}, until=("demographics",), page=page).step == "demographics"
        return pid
    with ThreadPoolExecutor(max_workers=12) as pool:
        list(pool.map(one, [f"h{i}" for i in range(36)] + ["dup"] * 6))
    with app.app_context():
        people = db.session.query(Participant).all()
        assert len(people) == 37
        counts = Counter(p.row for p in people)
        assert max(counts.values()) - min(counts.values()) <= 1
