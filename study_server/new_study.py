"""A new study in one command (``scenesuggest study init DIR``): a study file with every key, commented, that
validates and runs as it is; a practice scene and one target scene; a README of the next steps.

The study file comes from ``starter/study.toml`` (the demo's keys and comments, with this study's id, title,
corpus, scenes and completion codes filled in; a test keeps its keys the demo's). Nothing is ever overwritten:
the folder is built beside its place and renamed into it, which must be free (absent or an empty folder).
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
from pathlib import Path
from string import Template

from scenesuggest.atomic import temporary_folder_beside
from scenesuggest.errors import SceneSuggestError

from .config import PACKAGE

STARTER = PACKAGE / "starter"
DEMO_SCENES = PACKAGE / "demo" / "scenes"
#: The scenes a new study starts with: (study scene id, title, the demo scene file it copies).
PRACTICE = ("practice", "Practice: a dining table", "practice.json")
TARGET = ("desk-corner", "A desk corner", "desk-corner.json")
CORPORA = ("ai2thor",)


class InitError(SceneSuggestError):
    pass


def study_id_for(folder: Path) -> str:
    """A study id from a folder name: lower case letters, digits, '-' and '_'."""
    slug = re.sub(r"[^a-z0-9_-]+", "-", folder.resolve().name.lower()).strip("-_")
    return slug or "study"


def completion_code(rng: secrets.SystemRandom, outcome: str) -> str:
    """A code nobody can guess: 12 characters of an unambiguous alphabet, then the outcome (``K7QW…-DONE``)."""
    alphabet = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"
    return "".join(rng.choice(alphabet) for _ in range(12)) + "-" + outcome


def study_file_text(study_id: str, title: str, corpus: str) -> str:
    """The new study file: the starter template with this study's values (codes made at random)."""
    rng = secrets.SystemRandom()
    return Template((STARTER / "study.toml").read_text(encoding="utf-8")).substitute(
        id=study_id, title=json.dumps(title, ensure_ascii=False), corpus=corpus, target=TARGET[0],
        target_title=TARGET[1], code_complete=completion_code(rng, "DONE"),
        code_no_consent=completion_code(rng, "NOCONSENT"), code_screened_out=completion_code(rng, "SCREENED"),
        code_returned=completion_code(rng, "RETURNED"),
        code_technical=completion_code(rng, "TECHNICAL"))


def readme_text(folder: Path, study_id: str, title: str) -> str:
    return Template((STARTER / "README.md").read_text(encoding="utf-8")).substitute(
        id=study_id, title=title, file=str(folder.resolve() / "study.toml"))


def init_study(folder: str | Path, corpus: str = "ai2thor", title: str | None = None,
               study_id: str | None = None) -> list[Path]:
    """Write a new study into ``folder`` (absent or empty); returns the files written. Raises
    :class:`InitError` naming what is wrong (a folder in use, an unknown corpus, a bad id)."""
    folder = Path(folder)
    if corpus not in CORPORA:
        raise InitError(f"{corpus!r} is not a corpus a new study can start from (one of: {', '.join(CORPORA)})",
                        field="--corpus")
    study_id = study_id or study_id_for(folder)
    if not re.fullmatch(r"[A-Za-z0-9_-]+", study_id):
        raise InitError(f"{study_id!r}: use letters, digits, '-' and '_' only", field="--id")
    title = (title or study_id.replace("-", " ").replace("_", " ").capitalize()).strip()
    if not title or any(ord(c) < 32 for c in title):
        raise InitError("expected a title on one line", field="--title")
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise InitError("already exists and is not an empty folder: nothing was written (a new study never "
                        "overwrites anything)", file=str(folder))
    tmp = temporary_folder_beside(folder)
    try:
        (tmp / "scenes").mkdir()
        (tmp / "study.toml").write_text(study_file_text(study_id, title, corpus), encoding="utf-8")
        (tmp / "README.md").write_text(readme_text(folder, study_id, title), encoding="utf-8")
        for _, _, name in (PRACTICE, TARGET):
            shutil.copyfile(DEMO_SCENES / name, tmp / "scenes" / name)
        os.rename(tmp, folder)  # over an empty folder at most: anything written there meanwhile stops it
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return sorted(p for p in folder.rglob("*") if p.is_file())
