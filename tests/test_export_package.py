"""An export describes itself: ``datapackage.json`` is a Frictionless Data Package whose Table Schemas (types, keys,
allowed and missing values) come from the same description as ``data_dictionary.md``; ``frictionless validate``
passes on an exported study on both databases and fails on a broken cell or a changed file; the analysis reads the
columns' types from it."""

from __future__ import annotations

import csv
import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from demostudy import make_app
from support import lacking

from analysis.load import read_export
from simulation.participant import Bot
from simulation.transport import FlaskTransport
from study_server.experimenter.export import export_to
from study_server.experimenter.export_schema import TABLES


def validate(folder: Path) -> dict:
    """``frictionless validate`` of the package in ``folder``, as its JSON report."""
    cli = Path(sys.executable).parent / "frictionless"
    if not cli.exists():
        lacking("the frictionless command is not installed (pip install -e '.[test]')")
    done = subprocess.run([str(cli), "validate", "--json", "datapackage.json"], cwd=folder, capture_output=True,
                          text=True, timeout=300)
    return json.loads(done.stdout)


def errors(report: dict) -> list[str]:
    return [e["type"] for task in report["tasks"] for e in task["errors"]]


def export_of_bots(tmp_path: Path, url: str | None = None) -> Path:
    """The export of a demo study that two simulated participants completed."""
    app = make_app(tmp_path, url)
    for i in range(2):
        assert Bot(FlaskTransport(app.test_client()), "demo", f"bot-{i}", np.random.default_rng(i)).run().code
    with app.app_context():
        export_to(app.extensions["studies"]["demo"], tmp_path / "export")
    return tmp_path / "export"


@pytest.fixture
def exported(tmp_path, demo_resources) -> Path:
    return export_of_bots(tmp_path)


def test_an_export_is_a_valid_data_package_described_once(tmp_path, backend_url):
    exported = export_of_bots(tmp_path, backend_url)
    report = validate(exported)
    assert report["valid"], errors(report)
    assert {t["name"]: t["stats"]["rows"] for t in report["tasks"]}["events"] > 100
    package = json.loads((exported / "datapackage.json").read_text())
    manifest = json.loads((exported / "manifest.json").read_text())
    assert manifest["files"]["datapackage.json"] == hashlib.sha256((exported / "datapackage.json").read_bytes()) \
        .hexdigest()
    dictionary = (exported / "data_dictionary.md").read_text()
    for table, resource in zip(TABLES, package["resources"], strict=True):
        with (exported / resource["path"]).open() as f:
            header = next(csv.reader(f))
        fields = resource["schema"]["fields"]
        assert header == [f["name"] for f in fields] == [c.name for c in table.columns]
        for c, f in zip(table.columns, fields, strict=True):  # one description, two renderings
            assert f["description"] == c.description and f"| {c.name} | {c.type} | {c.description}" in dictionary
        assert resource["hash"] == "sha256:" + manifest["files"][resource["path"]]
    trials = next(r for r in package["resources"] if r["name"] == "trials")["schema"]
    condition = next(f for f in trials["fields"] if f["name"] == "condition")
    assert condition["constraints"]["enum"] == ["none", "basic", "full"]  # the study's own
    assert trials["foreignKeys"][0]["reference"] == {"resource": "participants", "fields": ["participant"]}
    # Psych-DS: a schema.org Dataset naming every variable measured
    assert package["@type"] == "Dataset" and package["name"] == "demo" and package["description"]
    headers = {c.name for t in TABLES for c in t.columns}
    assert sorted(v["name"] for v in package["variableMeasured"]) == sorted(headers)  # named as the columns


def test_allowed_ids_are_the_studys_and_the_datas_as_the_cells_hold_them(demo_resources):
    """A scene the study file no longer names still describes the data that holds it; an id a spreadsheet would run
    as a formula is allowed as the cell writes it (escaped)."""
    from demostudy import DEMO_STUDY

    from study_server.experimenter.export_schema import data_package
    from study_server.studies.study_file import load_study

    study = load_study(DEMO_STUDY)
    files = {f"{t.name}.csv": "0" * 64 for t in TABLES}
    package = data_package(study, files, "2026-12-04T00:00:00+00:00", {"scenes": {"-gone", *study.scenes}})
    trials = next(r for r in package["resources"] if r["name"] == "trials")["schema"]["fields"]
    allowed = next(f for f in trials if f["name"] == "scene")["constraints"]["enum"]
    assert allowed == [*study.scenes, "'-gone"]


def test_a_broken_cell_a_dangling_participant_or_a_changed_file_fails_validation(exported, tmp_path):
    def broken(name: str, change) -> dict:
        copy = tmp_path / name
        shutil.copytree(exported, copy)
        change(copy)
        return validate(copy)

    def cell(folder: Path, value: str, hashed: bool = True) -> None:
        path = folder / "trials.csv"
        lines = path.read_text().split("\n")
        lines[1] = value + lines[1][lines[1].index(","):]  # the first row's participant
        path.write_text("\n".join(lines))
        if hashed:  # the package says the file's new digest: only the content is wrong
            package = json.loads((folder / "datapackage.json").read_text())
            next(r for r in package["resources"] if r["name"] == "trials")["hash"] = \
                "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()
            (folder / "datapackage.json").write_text(json.dumps(package))

    assert "type-error" in errors(broken("type", lambda f: cell(f, "one")))
    assert "foreign-key" in errors(broken("key", lambda f: cell(f, "999")))
    assert "hash-count" in errors(broken("hash", lambda f: cell(f, "2", hashed=False)))


def test_the_analysis_reads_each_column_as_the_package_types_it(exported):
    """Text stays text even where every value looks like a number ("007", "1"): the schema says so."""
    path = exported / "survey.csv"
    rows = list(csv.DictReader(path.open()))
    for i, row in enumerate(rows):
        row["question"], row["answer"] = str(i + 1), "007"
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    data = read_export(exported)
    assert data.survey["question"].tolist()[:3] == ["1", "2", "3"] and set(data.survey["answer"]) == {"007"}
    assert data.trials["trial"].dtype == np.int64 and data.events["trial"].dtype == np.float64
