"""`scenesuggest study export`: tidy tables and a manifest from the database."""

import csv
import hashlib
import json
import os
import subprocess
import sys

from flowhelp import EXIT, csrf, finish_all_trials, to_trials


def test_export_command_writes_tidy_tables(app, tmp_path):
    c = app.test_client()
    b = to_trials(c)
    finish_all_trials(c, b)
    page = c.get("/study/demo/")
    c.post("/study/demo/exit", data={"csrf_token": csrf(page), **EXIT, "last_seq": "29", "attempt": "0"})
    out = tmp_path / "export"
    env = {**os.environ, "SCENESUGGEST_INSTANCE": str(tmp_path / "instance")}
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "export", "--study", "demo", "--db",
                           app.config["SQLALCHEMY_DATABASE_URI"], "--out", str(out), "--json"],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads(proc.stdout)
    assert manifest["row_counts"]["events"] == 30 and manifest["row_counts"]["trials"] == 10
    assert manifest["row_counts"]["participants"] == 1 and manifest["schema_version"]
    assert manifest["study_hash"] == app.extensions["studies"]["demo"].study.hash
    study = app.extensions["studies"]["demo"].study  # the priors and library it ran with, which its hash omits
    assert manifest["resources"] == {
        "corpus": "ai2thor", "server_resources": True,
        "priors_sha256": hashlib.sha256(study.priors.read_bytes()).hexdigest(),
        "library_index_sha256": hashlib.sha256((study.library / "library.json").read_bytes()).hexdigest()}
    for name, digest in manifest["files"].items():
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == digest
    assert out.stat().st_mode & 0o777 == 0o700  # what participants did is the operator's alone, as backups are
    assert {f.name: f.stat().st_mode & 0o777 for f in out.iterdir()} == {f.name: 0o600 for f in out.iterdir()}
    with (out / "trials.csv").open() as f:
        trials = list(csv.DictReader(f))
    assert [t["trial"] for t in trials] == [str(i) for i in range(-1, 9)]
    assert {t["condition"] for t in trials[1:]} == {"none", "basic", "full"}
    with (out / "survey.csv").open() as f:
        survey = {(r["survey"], r["question"]): r["answer"] for r in csv.DictReader(f)}
    assert survey[("exit", "preference")] == "Suggestions, oriented" and survey[("demographics", "age")] == "31"
    assert "## events.csv" in (out / "data_dictionary.md").read_text()
    bad = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "export", "--study", "nope", "--db",
                          app.config["SQLALCHEMY_DATABASE_URI"], "--out", str(tmp_path / "x")], capture_output=True,
                         text=True, env=env)
    assert bad.returncode == 2 and "no study 'nope'" in bad.stderr
