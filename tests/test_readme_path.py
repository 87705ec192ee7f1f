"""The README leads an experimenter: the commands of "Running a study, step by step" run as printed, in order, on
a fresh instance — a new study, validated, served, piloted apart, reset, taken by participants (where the README says
the platform sends them), exported and analysed in Python and in R — and each step leaves what the README says."""

from __future__ import annotations

import os
import re
import signal
import sqlite3
import subprocess
import threading
import time
from urllib.parse import parse_qsl, urlsplit

import pandas as pd
import pytest
from flowhelp import DEMOGRAPHICS
from serverproc import free_port
from support import ROOT, require_lme4

from simulation.run import simulate
from simulation.transport import FlowError, HttpTransport
from simulation.walker import Walker

SECTION = "## Running a study, step by step"


def readme_path() -> list[tuple[int, str]]:
    """(step, command) of the README's block, in order (a command's step is the last "# N." comment above it)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split(SECTION, 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    out, step = [], 0
    for line in block.splitlines():
        numbered = re.match(r"# (\d+)\.", line)
        if numbered:
            step = int(numbered.group(1))
            out.append((step, ""))  # a step of its own, even when it has no command
        elif line.strip() and not line.startswith("#"):
            out.append((step, line.strip()))
    return out


def test_the_path_names_each_step_with_a_command():
    steps = readme_path()
    assert [s for s, c in steps if not c] == list(range(1, 8))
    commands = [c for _, c in steps if c]
    assert all(c.startswith((".venv/bin/scenesuggest ", "SCENESUGGEST_STUDIES=", "Rscript ")) for c in commands)
    for word in ("study init", "study validate", "study serve", "study simulate", "study reset", "study export",
                 "analyze report", "reproduce.R"):
        assert any(word in c for c in commands), word


class Served:
    """The README's `study serve … &`, on a free port, its output kept."""

    def __init__(self, command: str, cwd, env, port: int):
        self.port, self.lines = port, []
        self.proc = subprocess.Popen(["bash", "-c", command.removesuffix("&").strip() + f" --port {port}"], cwd=cwd,
                                     env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True)
        threading.Thread(target=lambda: self.lines.extend(self.proc.stdout), daemon=True).start()
        base = f"http://127.0.0.1:{port}"
        end = time.time() + 180
        while time.time() < end:
            if self.proc.poll() is not None:
                raise AssertionError("the server stopped: " + "".join(self.lines))
            try:
                if HttpTransport(base).get("/healthz").status == 200:
                    self.base = base
                    return
            except (OSError, FlowError):  # not listening yet
                pass
            time.sleep(0.5)
        raise AssertionError("the server never answered: " + "".join(self.lines))

    def said(self, prefix: str) -> str:
        return next(line.split(": ", 1)[1].strip() for line in self.lines if line.startswith(prefix))

    def stop(self) -> None:
        os.killpg(self.proc.pid, signal.SIGTERM)
        self.proc.wait(timeout=30)


def _participants(db) -> list[tuple]:
    with sqlite3.connect(db) as con:
        return con.execute("SELECT platform_id, pilot, status FROM participants ORDER BY id").fetchall()


@pytest.mark.slow
def test_the_readme_path_runs_as_printed_on_a_fresh_instance(tmp_path, demo_resources):
    rscript = require_lme4()
    (tmp_path / ".venv").symlink_to(ROOT / ".venv")
    home = tmp_path / "var"  # a fresh instance; the models and priors the demo built are lent to it
    home.mkdir()
    for built in ("priors", "library"):
        (home / built).symlink_to(ROOT / "var" / built)
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "SCENESUGGEST_INSTANCE",
                                                            "SCENESUGGEST_STUDIES")}
    env["SCENESUGGEST_HOME"] = str(home)
    database = home / "instance" / "studies.sqlite3"
    served = None
    try:
        for step, command in readme_path():
            if step == 5 and not command:  # a pilot took the study on the server, through the printed test link
                assert _participants(database) == []  # the simulated pilots went elsewhere
                link = urlsplit(served.said("test link"))
                page = Walker(HttpTransport(served.base), "my-study").to_first_trial(
                    dict(parse_qsl(link.query)), lambda _: DEMOGRAPHICS)
                assert page.step == "trial"  # consented: a row taken, as a pilot
                assert [(pilot, status) for _, pilot, status in _participants(database)] == [(1, "in_progress")]
            if step == 6 and not command:  # the platform's participants take the study
                assert _participants(database) == []  # step 5 removed the pilot
                done = simulate(2, seed=7, study="my-study", url=served.base)
                assert done["completed"] == 2 and not done["failures"]
            if not command:
                continue
            if command.endswith("&"):
                served = Served(command, tmp_path, env, free_port())
                assert served.said("participants' link (link)") == f"{served.base}/study/my-study/start"
                continue
            ran = subprocess.run(["bash", "-c", command.replace("Rscript ", f"{rscript} ", 1)], cwd=tmp_path,
                                 env=env, capture_output=True, text=True, timeout=600)
            assert ran.returncode == 0, f"step {step}: {command}\n{ran.stdout}\n{ran.stderr}"
            if "study simulate" in command:
                assert "pilot database, apart from the study's own" in ran.stdout
    finally:
        if served is not None:
            served.stop()
    pilots = pd.read_csv(tmp_path / "var" / "pilot-export" / "participants.csv")
    assert len(pilots) == 6 and pilots["pilot"].all()
    assert "**Pilot data only:**" in (tmp_path / "var" / "pilot-report" / "README.md").read_text()
    people = pd.read_csv(tmp_path / "var" / "export" / "participants.csv")
    assert len(people) == 2 and not people["pilot"].any() and (people["status"] == "completed").all()
    report = (tmp_path / "var" / "report" / "README.md").read_text()
    assert "- N: 2 participants arrived, 2 completed" in report
    assert (tmp_path / "experiments" / "my-study" / "README.md").read_text().count("study.toml") >= 5
