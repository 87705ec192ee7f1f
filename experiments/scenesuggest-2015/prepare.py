"""Prepare the SceneSuggest replication from your copy of the Stanford Scene Database.

Writes, under ``var/experiments/scenesuggest-2015/`` (never committed):

    library/            the study's model library: one representative per top-100 category (GLB + thumbnails),
                        plus any --extra-models
    priors.npz          priors trained on the corpus without the targets' source scenes
    scenes/<id>.json    the practice scene and the six target scenes (native scene JSON)
    manifest.json       what went in: corpus, representatives, held-out scenes, counts

The corpus folder comes from ``--stanford-dir`` or ``$SCENESUGGEST_STANFORD_DIR``; meshes are found as for
every Stanford command (``--meshes``, ``$SCENESUGGEST_STANFORD_MESHES``, ``DIR/models``,
``DIR/../stanford_models/models``). The representatives are read from ``--representatives``, else from
``representatives.tsv`` beside the mesh folder, else chosen from the corpus by the same rule. Steps whose
inputs have not changed are skipped.

    .venv/bin/python experiments/scenesuggest-2015/prepare.py [--stanford-dir DIR]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
OUT = ROOT / "var" / "experiments" / HERE.name
sys.path.insert(0, str(HERE))

from targets import TARGETS, compose, held_out  # noqa: E402

from scenesuggest.assets.build import build_library  # noqa: E402
from scenesuggest.corpora import load_corpus  # noqa: E402
from scenesuggest.corpora.representatives import FILE_NAME, study_representatives  # noqa: E402
from scenesuggest.corpora.stanford import find_mesh_dir  # noqa: E402
from scenesuggest.errors import SceneSuggestError  # noqa: E402
from scenesuggest.learning.priors import VERSION as PRIORS_VERSION  # noqa: E402
from scenesuggest.learning.priors import Priors, code_digest  # noqa: E402
from scenesuggest.library.index import INDEX_FILE, load_index  # noqa: E402
from scenesuggest.scenes import scene_json  # noqa: E402

ENV = "SCENESUGGEST_STANFORD_DIR"


def stanford_dir(option: str | None) -> Path:
    value = option or os.environ.get(ENV)
    if not value:
        raise SceneSuggestError(f"where is your copy of the Stanford Scene Database? Pass --stanford-dir DIR or "
                                f"set {ENV} (DIR holds scenes/sceneNNNNN.txt)", field="stanford_dir")
    path = Path(value)
    if not (path / "scenes").is_dir():
        raise SceneSuggestError(f"{path} has no scenes/ folder: not a Stanford Scene Database copy",
                                field="stanford_dir")
    return path


def library_models(corpus, reps: list[tuple[str, str]], extra: list[str]) -> list[str]:
    """The study library's model ids: the representatives plus ``extra`` models (ids with a mesh), as the paper
    added the extra chairs and tables its targets needed."""
    for model_id in extra:
        if model_id not in corpus.models:
            raise SceneSuggestError(f"no model {model_id!r} in the corpus", field="extra_models")
        if corpus.models[model_id].mesh is None:
            raise SceneSuggestError(f"model {model_id!r} has no mesh to build from", field="extra_models")
    return sorted({m for _, m in reps} | set(extra))


def digest(value) -> str:
    return hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()[:16]


def prepare(stanford: Path, out: Path = OUT, representatives_file: str | None = None, meshes: str | None = None,
            extra_models: list[str] = (), log=print) -> dict:
    started = time.perf_counter()
    corpus = load_corpus(f"stanford:{stanford}", meshes=meshes)
    mesh_dir = find_mesh_dir(stanford, meshes)
    reps, reps_from = study_representatives(corpus, mesh_dir, representatives_file)
    model_ids = library_models(corpus, reps, list(extra_models))
    out.mkdir(parents=True, exist_ok=True)
    manifest_path = out / "manifest.json"
    old = json.loads(manifest_path.read_text()) if manifest_path.is_file() else {}

    library_key = digest(model_ids)
    if old.get("library_key") != library_key or not (out / "library" / INDEX_FILE).is_file():
        log(f"building {len(model_ids)} models into {out / 'library'} …")
        report = build_library(corpus, out / "library", model_ids)
        log(f"built {report['built']} models in {report['seconds']:.0f} s")
    held = held_out()
    missing = [s for s in held if s not in {x.id for x in corpus.scenes}]
    if missing:
        raise SceneSuggestError(f"the corpus lacks the targets' source scenes {', '.join(missing)}",
                                field="stanford_dir")
    training = [s for s in corpus.scenes if s.id not in set(held)]
    priors_key = digest([sorted(s.id for s in training), PRIORS_VERSION, code_digest()])
    if old.get("priors_key") != priors_key or not (out / "priors.npz").is_file():
        log(f"training priors on {len(training)} scenes (holding out {', '.join(held)}) …")
        Priors.fit(training, corpus.taxonomy).save(out / "priors.npz")

    library = load_index(out / "library")
    by_name = {category: library[model_id] for category, model_id in reps}
    (out / "scenes").mkdir(exist_ok=True)
    counts = {}
    for target_id in TARGETS:
        scene = compose(target_id, by_name, corpus.taxonomy)
        scene_json.save(scene, out / "scenes" / f"{target_id}.json")
        counts[target_id] = len(scene) - 1
    manifest = {
        "corpus": str(stanford.resolve()), "scenes_in_corpus": len(corpus.scenes),
        "representatives": reps_from, "models": len(model_ids), "held_out": held,
        "training_scenes": len(training), "targets": counts,
        "library_key": library_key, "priors_key": priors_key,
    }
    manifest_path.write_text(json.dumps(manifest, indent=1) + "\n")
    log(f"prepared {out} in {time.perf_counter() - started:.0f} s: {len(model_ids)} models, priors on "
        f"{len(training)} scenes, targets {counts}")
    return manifest


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--stanford-dir", help=f"the Stanford Scene Database folder (default: ${ENV})")
    parser.add_argument("--meshes", help="folder of the OBJ meshes (default: as for every Stanford command)")
    parser.add_argument("--representatives", help=f"a {FILE_NAME} file (default: beside the mesh folder)")
    parser.add_argument("--extra-models", default="", help="comma-separated model ids to add to the library "
                        "(models with a mesh; the targets here need none)")
    parser.add_argument("--out", default=str(OUT), help="output folder (default: %(default)s)")
    args = parser.parse_args(argv)
    try:
        extra = [m for m in args.extra_models.split(",") if m.strip()]
        prepare(stanford_dir(args.stanford_dir), Path(args.out), args.representatives, args.meshes, extra)
    except SceneSuggestError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
