"""Functions run in separate processes by the concurrency tests (importable by multiprocessing's spawn)."""

from __future__ import annotations


def arrive_many(args) -> list[tuple[str, int, int]]:
    database_url, instance, study_file, pids = args
    from study_server import create_app
    from study_server.participants.assignment import arrive, assign

    app = create_app({"INSTANCE_PATH": instance, "SQLALCHEMY_DATABASE_URI": database_url,
                      "STUDY_FILES": [study_file], "SECRET_KEY": "x", "CHECK_RESOURCES": False})
    out = []
    with app.app_context():
        study = app.extensions["studies"]["demo"].study
        for pid in pids:
            p, created = arrive(study, "link", pid)
            assign(study, p)
            out.append((pid, p.id, p.row))
    return out
