"""A new study in one command (``scenesuggest study init DIR``): a study file with every key, commented, that
validates and runs as it is; a practice scene and one target scene; a README of the next steps.

On the built-in ``ai2thor`` corpus the scenes are the demo's and the server builds its own priors and model
library for the corpus. On a copy of the Stanford Scene Database (``stanford:DIR``) the study gets its own, as
the paper built them: a library of one representative model per top-100 category (``library/stanford``),
priors trained on every scene of the corpus (``priors/stanford.npz``; the starter scenes are composed here, not
taken from the corpus, so nothing of them is in training), and a practice and a target scene composed from the
library's models.

The study file comes from ``starter/study.toml`` (the demo's keys and comments, with this study's id, title,
corpus, scenes and completion codes filled in; a test keeps its keys the demo's). Nothing is ever overwritten:
the folder is built beside its place and renamed into it, which must be free (absent or an empty folder).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import shlex
import shutil
import sys
import unicodedata
from pathlib import Path
from string import Template

from scenesuggest.atomic import temporary_folder_beside
from scenesuggest.errors import SceneSuggestError
from scenesuggest.library.authoring import SceneAuthor
from scenesuggest.scenes import scene_json
from scenesuggest.scenes.scene_types import infer_scene_type

from ..base.config import PACKAGE

STARTER = PACKAGE / "starter"
DEMO_SCENES = PACKAGE / "demo" / "scenes"
#: The scenes a new study starts with: (study scene id, title, the demo scene file it copies).
PRACTICE = ("practice", "Practice: a dining table", "practice.json")
TARGET = ("desk-corner", "A desk corner", "desk-corner.json")
CORPORA = ("ai2thor", "stanford:DIR")
MAX_ID, MAX_TITLE = 64, 200  # a study id goes into URLs, file names and exports; a title onto every page
#: The [resources] table of a study on the built-in corpus: the server's own priors and library.
SERVER_RESOURCES = """corpus = "ai2thor"
# priors = "priors/ai2thor.npz"   # a priors file ('scenesuggest priors train CORPUS -o FILE') and
# library = "library/ai2thor"     # a model library ('scenesuggest assets build CORPUS --out DIR'); without them the
#                                 # server's own for the corpus, which 'scenesuggest study prepare' builds"""
#: The [resources] table of a study on a Stanford Scene Database copy: its own priors and library, built here.
STANFORD_RESOURCES = """corpus = $corpus
priors = "priors/stanford.npz"    # trained on every scene of the corpus by 'scenesuggest study init' (retrain:
#                                 # 'scenesuggest priors train CORPUS -o FILE')
library = "library/stanford"      # one representative model per top-100 category of the corpus (rebuild:
#                                 # 'scenesuggest assets build CORPUS --out DIR')"""
STANFORD_PRACTICE_TITLE = "Practice: a side table"
#: The representative categories :func:`side_table` and :func:`desk_corner` compose the starter scenes from.
STARTER_CATEGORIES = {"EndTable", "Mug", "Clock", "Desk", "Monitor", "Keyboard", "DeskLamp", "OfficeChair", "Poster"}
ROOM = (5.0, 2.7, 4.0)  # metres: width X, height Y, depth Z; the back wall is at z = -2
BACK = -ROOM[2] / 2


class InitError(SceneSuggestError):
    pass


def study_id_for(folder: Path) -> str:
    """A study id from a folder name: lower case letters, digits, '-' and '_' (at most ``MAX_ID``). Accents are
    dropped ("Étude" → "etude"); a name with no Latin letters gets ``study-`` and 8 hex digits of its SHA-256,
    so two such folders get two ids."""
    name = folder.resolve().name
    plain = unicodedata.normalize("NFKD", name).encode("ascii", "ignore").decode().lower()
    slug = re.sub(r"[^a-z0-9_-]+", "-", plain)[:MAX_ID].strip("-_")
    if slug:
        return slug
    return "study-" + hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:8] if name else "study"


def completion_code(rng: secrets.SystemRandom, outcome: str) -> str:
    """A code nobody can guess: 12 characters of an unambiguous alphabet, then the outcome (``K7QW…-DONE``)."""
    alphabet = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"
    return "".join(rng.choice(alphabet) for _ in range(12)) + "-" + outcome


def study_file_text(study_id: str, title: str, resources: str, practice_title: str) -> str:
    """The new study file: the starter template with this study's values (codes made at random)."""
    rng = secrets.SystemRandom()
    return Template((STARTER / "study.toml").read_text(encoding="utf-8")).substitute(
        id=study_id, title=json.dumps(title, ensure_ascii=False), resources=resources,
        practice_title=practice_title, target=TARGET[0],
        target_title=TARGET[1], code_complete=completion_code(rng, "DONE"),
        code_no_consent=completion_code(rng, "NOCONSENT"), code_screened_out=completion_code(rng, "SCREENED"),
        code_returned=completion_code(rng, "RETURNED"),
        code_technical=completion_code(rng, "TECHNICAL"))


def readme_text(study_id: str, title: str) -> str:
    """The next steps, as commands run in the study's folder (which may move: no path of it is written)."""
    return Template((STARTER / "README.md").read_text(encoding="utf-8")).substitute(
        id=study_id, title=title, cmd=command())


def command() -> str:
    """How to run ``scenesuggest`` here: by its name when that is what PATH finds, else by its path (a checkout's
    ``.venv/bin/scenesuggest``, shell-quoted)."""
    beside = Path(sys.executable).parent / "scenesuggest"
    found = shutil.which("scenesuggest")
    if not beside.exists() or (found and Path(found).resolve() == beside.resolve()):
        return "scenesuggest"
    return shlex.quote(str(beside))


def stanford_folder(corpus: str) -> Path | None:
    """The folder of a ``stanford:DIR`` corpus (checked), or None for the built-in corpus."""
    if corpus == "ai2thor":
        return None
    kind, _, arg = corpus.partition(":")
    if kind != "stanford" or not arg:
        raise InitError(f"{corpus!r} is not a corpus a new study can start from (one of: {', '.join(CORPORA)})",
                        field="--corpus")
    path = Path(arg).expanduser()
    if not (path / "scenes").is_dir():
        raise InitError(f"{path} has no scenes/ folder: not a copy of the Stanford Scene Database", field="--corpus")
    return path.resolve()


def init_study(folder: str | Path, corpus: str = "ai2thor", title: str | None = None,
               study_id: str | None = None, meshes: str | Path | None = None, say=lambda message: None) -> list[Path]:
    """Write a new study into ``folder`` (absent or empty); returns the files written (a library as its
    folder). ``meshes``: the Stanford mesh folder (default: as for every Stanford command); ``say`` hears
    progress. Raises :class:`InitError` naming what is wrong (a folder in use, an unknown corpus, a bad id, a
    corpus the starter scenes need more of)."""
    for value, field in ((str(folder), "FOLDER"), (corpus, "--corpus"), (str(meshes or ""), "--meshes"),
                         (study_id or "", "--id"), (title or "", "--title")):
        if "\0" in value or any(0xD800 <= ord(c) <= 0xDFFF for c in value):
            raise InitError("holds a NUL or a character that is not UTF-8 (a lone surrogate)", field=field)
    folder = Path(folder).absolute()
    if ":" in str(folder):
        raise InitError("holds ':', which separates the study files in SCENESUGGEST_STUDIES: the server could not "
                        "be given this study; choose another folder", file=str(folder))
    stanford = stanford_folder(corpus)
    if meshes is not None and stanford is None:
        raise InitError("only a Stanford corpus has meshes to find", field="--meshes")
    if meshes is not None and not Path(meshes).is_dir():
        raise InitError(f"{meshes}: no such folder (expected the corpus's OBJ meshes)", field="--meshes")
    study_id = study_id or study_id_for(folder)
    if not re.fullmatch(rf"[A-Za-z0-9_-]{{1,{MAX_ID}}}", study_id):
        raise InitError(f"{study_id[:80]!r}: use 1 to {MAX_ID} letters, digits, '-' and '_'", field="--id")
    title = (title or study_id.replace("-", " ").replace("_", " ").capitalize()).strip()
    if not title or len(title) > MAX_TITLE or any(unicodedata.category(c) == "Cc" for c in title):
        raise InitError(f"expected a title of 1 to {MAX_TITLE} characters on one line, without control "
                        "characters", field="--title")
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise InitError("already exists and is not an empty folder: nothing was written (a new study never "
                        "overwrites anything)", file=str(folder))
    try:
        tmp = temporary_folder_beside(folder)
    except OSError as e:
        raise InitError(f"cannot make the study folder there ({e.strerror or e})", file=str(folder)) from None
    try:
        (tmp / "scenes").mkdir()
        if stanford is None:
            resources, practice_title = SERVER_RESOURCES, PRACTICE[1]
            for _, _, name in (PRACTICE, TARGET):
                shutil.copyfile(DEMO_SCENES / name, tmp / "scenes" / name)
        else:
            write_stanford_resources(tmp, stanford, meshes, say)
            resources = Template(STANFORD_RESOURCES).substitute(
                corpus=json.dumps(f"stanford:{stanford}", ensure_ascii=False))
            practice_title = STANFORD_PRACTICE_TITLE
        private = os.open(tmp / "study.toml", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)  # it holds the codes
        with os.fdopen(private, "w", encoding="utf-8") as f:
            f.write(study_file_text(study_id, title, resources, practice_title))
        (tmp / "README.md").write_text(readme_text(study_id, title), encoding="utf-8")
        _move_in(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    library = folder / "library"
    return sorted([p for p in folder.rglob("*") if p.is_file() and library not in p.parents]
                  + ([library / "stanford"] if library.is_dir() else []))


def _move_in(tmp: Path, folder: Path) -> None:
    """Put the finished ``tmp`` in place: renamed to ``folder`` when that is absent; into it, entry by entry, when
    it is an empty folder (which stays the same folder: someone's working directory stays valid)."""
    if not folder.exists():
        try:
            os.rename(tmp, folder)  # over an empty folder made meanwhile at most
        except OSError:
            raise InitError("was filled while the study was being made: nothing was written",
                            file=str(folder)) from None
        return
    if not folder.is_dir() or any(folder.iterdir()):
        raise InitError("was filled while the study was being made: nothing was written", file=str(folder))
    for entry in tmp.iterdir():
        os.rename(entry, folder / entry.name)
    tmp.rmdir()


def write_stanford_resources(out: Path, root: Path, meshes: str | Path | None, say) -> None:
    """Build into ``out`` a study's library (``library/stanford``), priors (``priors/stanford.npz``) and starter
    scenes (``scenes/``) from the Stanford Scene Database copy at ``root``."""
    from scenesuggest.assets.build import build_library
    from scenesuggest.corpora import load_corpus
    from scenesuggest.corpora.representatives import study_representatives
    from scenesuggest.corpora.stanford import MESHES_ENV, find_mesh_dir
    from scenesuggest.learning.priors import Priors
    from scenesuggest.library.index import load_index

    mesh_dir = find_mesh_dir(root, meshes)
    if mesh_dir is None:
        raise InitError(f"no meshes for the corpus at {root}: pass --meshes DIR or set {MESHES_ENV} (a folder of "
                        "OBJ meshes; default DIR/models or DIR/../stanford_models/models)", field="--meshes")
    corpus = load_corpus(f"stanford:{root}", meshes=mesh_dir)
    reps, origin = study_representatives(corpus, mesh_dir)
    lacking = sorted(STARTER_CATEGORIES - {category for category, _ in reps})
    if lacking:
        raise InitError(f"the starter scenes need a model of each of {', '.join(lacking)}, which the corpus's "
                        f"representatives ({origin}) lack", field="--corpus")
    library = out / "library" / "stanford"
    library.parent.mkdir()
    say(f"building the model library: {len(reps)} models, one per category ({origin}), about a minute …")
    build_library(corpus, library, sorted({model_id for _, model_id in reps}))
    say(f"training priors on the corpus's {len(corpus.scenes)} scenes …")
    (out / "priors").mkdir()
    Priors.fit(corpus.scenes, corpus.taxonomy).save(out / "priors" / "stanford.npz")
    index = load_index(library)
    models = {category: index[model_id] for category, model_id in reps}
    for scene_id, compose in ((PRACTICE[0], side_table), (TARGET[0], desk_corner)):
        author = SceneAuthor(scene_id, "Room", models, ROOM)
        compose(author)  # every category it needs is in STARTER_CATEGORIES, checked above
        author.scene.scene_type = infer_scene_type((o.category for o in author.scene), corpus.taxonomy)
        scene_json.save(author.scene, out / "scenes" / f"{scene_id}.json")


def side_table(a: SceneAuthor) -> None:
    """The practice scene: a side table against the back wall with a mug and a clock on it."""
    table = a.put("EndTable", "room", 0.0, BACK + 0.6)
    a.put("Mug", table, -0.15, BACK + 0.55, yaw_deg=30)
    a.put("Clock", table, 0.15, BACK + 0.6)


def desk_corner(a: SceneAuthor) -> None:
    """The target scene: a desk against the back wall with a monitor, keyboard, lamp and mug, a chair turned
    to face it, and a poster above it."""
    depth = a.size("Desk")[2]
    desk = a.put("Desk", "room", 0.0, BACK + depth / 2)
    a.put("Monitor", desk, 0.0, BACK + 0.2)
    a.put("Keyboard", desk, 0.0, BACK + 0.55)
    a.put("DeskLamp", desk, -0.6, BACK + 0.3)
    a.put("Mug", desk, 0.5, BACK + 0.5)
    a.put("OfficeChair", "room", 0.0, BACK + depth + 0.45, yaw_deg=180)  # facing the desk
    a.hang("Poster", "back", 0.0, 1.8)
