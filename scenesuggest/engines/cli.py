"""``scenesuggest engine …``: the registered engines, training one, and serving one over HTTP."""

from __future__ import annotations

import time
from pathlib import Path

import click

from ..console import SOURCE_HELP, emit, meshes_option, progress
from ..errors import SceneSuggestError
from . import configure, kind, names


@click.group()
def engine() -> None:
    """Engines by name: list them, train one, serve one over HTTP."""


@engine.command("list")
@click.option("--json", "as_json", is_flag=True)
def list_cmd(as_json: bool) -> None:
    """Every registered engine (built in, and those of installed packages: entry points 'scenesuggest.engines')."""
    found = []
    for name in names():
        try:
            found.append(kind(name).describe())
        except SceneSuggestError as e:
            found.append({"name": name, "error": e.message})
    lines = [f"{e['name']:<12} {'v' + e['version'] if 'version' in e else '':<5} "
             f"{'trainable' if e.get('trainable') else '':<10} {e.get('summary') or e.get('error')}" for e in found]
    emit({"engines": found}, as_json, "\n".join(lines))


@engine.command("train", help="Train the engine NAME on SOURCE (" + SOURCE_HELP + ") and write its file.")
@click.argument("name")
@click.argument("source")
@click.option("-o", "--out", "out", required=True, type=click.Path(dir_okay=False), help="The engine's file (.npz).")
@click.option("--seed", default=0, show_default=True, help="Folds and model training follow it.")
@meshes_option
@click.option("--json", "as_json", is_flag=True)
def train_cmd(name: str, source: str, out: str, seed: int, meshes: str | None, as_json: bool) -> None:
    from ..assets.symmetry import corpus_periods

    if not kind(name).trainable:  # before its options: an engine that needs some (http) is not trained here
        raise SceneSuggestError(f"the {name!r} engine is not trained by this project", field="name")
    spec = configure({"name": name})
    from ..corpora import load_corpus

    corpus = load_corpus(source, meshes=meshes, progress=progress)
    periods = corpus_periods(corpus.models.values(), progress)
    started = time.perf_counter()
    info = spec.kind.train(spec.config, corpus.scenes, corpus.taxonomy, Path(out), seed=seed, progress=progress,
                           periods=periods)
    info = {"engine": name, **info, "train_s": round(time.perf_counter() - started, 1)}
    emit(info, as_json, f"trained the {name} engine on {len(corpus.scenes)} scenes in {info['train_s']:.1f} s → "
                        f"{info['out']} ({info['bytes'] / 1e6:.1f} MB)")


@engine.command("serve")
@click.argument("name")
@click.option("--priors", "priors_file", required=True, type=click.Path(dir_okay=False),
              help="The engine's trained file (priors for paper and frequency, the learned engine's file).")
@click.option("--host", default="127.0.0.1", show_default=True)
@click.option("--port", default=8100, show_default=True, type=click.IntRange(0, 65535))
@click.option("--frames", is_flag=True, help="Turn each suggestion as the frame classifier chooses (learned).")
def serve_cmd(name: str, priors_file: str, host: str, port: int, frames: bool) -> None:
    """Serve the engine NAME over HTTP, as a study's 'http' engine asks (POST a query, JSON answer)."""
    from . import load
    from .protocol import LoadContext
    from .serve import make_server

    if frames and name != "learned":
        raise SceneSuggestError("--frames is an option of the learned engine", field="frames")
    spec = configure({"name": name, **({"file": priors_file, "frames": frames} if name == "learned" else {})})
    engine = load(spec, LoadContext(Path(priors_file)))
    server = make_server(engine, host, port)
    click.echo(f"serving the {name} engine on http://{host}:{server.server_address[1]}/ (Ctrl-C stops)", err=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
