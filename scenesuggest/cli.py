"""The ``scenesuggest`` command: the composition root that wires the library to the terminal.

Every command that computes something takes ``--json`` (one JSON document on stdout, nothing else);
progress goes to stderr. User errors print ``Error: FILE:LINE: field 'F': message`` and exit with 2.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable
from pathlib import Path

import click

from . import __version__
from .errors import SceneSuggestError

SOURCE_HELP = "stanford:DIR, ai2thor (the installed procthor package data) or json:DIR"


def progress(items: Iterable, label: str = "") -> Iterable:
    """Show a progress bar on stderr while iterating (just the label when stderr is not a terminal)."""
    items = list(items)
    with click.progressbar(items, label=label, file=sys.stderr, show_pos=True) as bar:
        yield from bar


def emit(data: dict, as_json: bool, human: str) -> None:
    if as_json:
        click.echo(json.dumps(data, indent=1))
    else:
        click.echo(human)


class _Group(click.Group):
    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except SceneSuggestError as e:
            click.echo(f"Error: {e}", err=True)
            ctx.exit(2)


@click.group(cls=_Group)
@click.version_option(__version__, prog_name="scenesuggest")
def main() -> None:
    """SceneSuggest: context-driven 3D scene design — corpora, priors, suggestions and user studies."""


def _load(source: str, meshes: str | None):
    from .corpora import load_corpus

    return load_corpus(source, meshes=meshes, progress=progress)


meshes_option = click.option("--meshes", type=click.Path(file_okay=False), default=None,
                             help="Folder of Stanford OBJ meshes (default: DIR/models, ../stanford_models/models "
                                  "or $SCENESUGGEST_STANFORD_MESHES).")


@main.group()
def corpus() -> None:
    """Scene corpora: statistics and conversion."""


@corpus.command("stats", help="Counts per scene type, category, support parent, surface type and attachment "
                                "face. SOURCE is " + SOURCE_HELP + ".")
@click.argument("source")
@meshes_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
@click.option("--top", default=15, show_default=True, help="Rows per section in the human format.")
def corpus_stats_cmd(source: str, meshes: str | None, as_json: bool, top: int) -> None:
    from .stats import corpus_stats, format_stats

    stats = corpus_stats(_load(source, meshes))
    emit(stats, as_json, format_stats(stats, top))


@corpus.command("convert")
@click.argument("source")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False), help="New folder (json:DIR layout).")
@meshes_option
@click.option("--json", "as_json", is_flag=True)
def corpus_convert_cmd(source: str, out: str, meshes: str | None, as_json: bool) -> None:
    """Write a corpus in the native JSON format (all or nothing)."""
    from .corpora.native import write_native

    c = _load(source, meshes)
    path = write_native(c, out, progress=progress)
    emit({"out": str(path), "scenes": len(c.scenes), "models": len(c.models)}, as_json,
         f"wrote {len(c.scenes)} scenes and {len(c.models)} models to json:{path}")


@main.command("search")
@click.argument("query")
@click.option("--source", default="ai2thor", show_default=True, help=SOURCE_HELP)
@click.option("--library", "library_dir", type=click.Path(file_okay=False), default=None,
              help="Search a built model library (its library.json) instead of a corpus.")
@meshes_option
@click.option("--limit", default=10, show_default=True)
@click.option("--json", "as_json", is_flag=True)
def search_cmd(query: str, source: str, library_dir: str | None, meshes: str | None, limit: int,
               as_json: bool) -> None:
    """Keyword search over model names, tags, categories and descriptions (BM25)."""
    from .library import load_index
    from .search import SearchIndex

    models = load_index(library_dir) if library_dir else _load(source, meshes).models
    hits = SearchIndex.build(models.values()).search(query, limit)
    human = "\n".join(f"{i + 1:>3}. {h.category:<20} {h.name:<40} {h.model_id}  ({h.score:.2f})"
                      for i, h in enumerate(hits)) or "no models match"
    emit({"query": query, "hits": [h.to_dict() for h in hits]}, as_json, human)


@main.group()
def assets() -> None:
    """Model library assets: GLB meshes, thumbnails and the library index."""


@assets.command("build")
@click.argument("source")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False))
@click.option("--models", "only", default=None, help="Comma-separated model ids (default: every model with a mesh).")
@click.option("--thumbnail-size", default=256, show_default=True, help="Thumbnail edge in pixels.")
@meshes_option
@click.option("--json", "as_json", is_flag=True)
def assets_build_cmd(source: str, out: str, only: str | None, thumbnail_size: int, meshes: str | None,
                     as_json: bool) -> None:
    """Convert meshes to GLB in the canonical frame, render thumbnails and write library.json.

    Stanford models need their OBJ files; AI2-THOR types get procedural low-poly meshes."""
    from .assets.build import build_library

    c = _load(source, meshes)
    ids = [m.strip() for m in only.split(",") if m.strip()] if only else None
    report = build_library(c, Path(out), model_ids=ids, thumbnail_px=thumbnail_size, progress=progress)
    emit(report, as_json, f"built {report['built']} models into {out} "
                          f"({report['skipped']} without a mesh, {report['seconds']:.1f} s)")


if __name__ == "__main__":  # pragma: no cover
    main()
