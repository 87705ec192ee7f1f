"""The ``scenesuggest`` command: the composition root that wires the library to the terminal.

Every command that computes something takes ``--json`` (one JSON document on stdout, nothing else);
progress goes to stderr. User errors print ``Error: FILE:LINE: field 'F': message`` and exit with 2.
"""

from __future__ import annotations

from pathlib import Path

import click

from . import __version__
from .console import SOURCE_HELP, emit, meshes_option, progress
from .errors import SceneSuggestError


class _Group(click.Group):
    #: Command groups of other packages, imported only when used: name → (module, attribute). The engine
    #: package imports neither the study server, the simulation nor the analysis.
    lazy = {"analyze": ("analysis.cli", "analyze"), "schedule": ("study_server.cli", "schedule"),
            "study": ("study_server.cli", "study"), "engine": ("scenesuggest.engines.cli", "engine")}
    #: Commands that other packages add to those groups: group → [(module, attribute)].
    extra = {"study": [("simulation.cli", "simulate_cmd"), ("simulation.cli", "calibrate_cmd"),
                       ("simulation.cli", "power_cmd")]}

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted([*super().list_commands(ctx), *self.lazy])

    def get_command(self, ctx: click.Context, name: str):
        if name not in self.lazy:
            return super().get_command(ctx, name)
        import importlib

        module, attribute = self.lazy[name]
        group = getattr(importlib.import_module(module), attribute)
        for module, attribute in self.extra.get(name, ()):
            group.add_command(getattr(importlib.import_module(module), attribute))
        return group

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
    from .corpora.stats import corpus_stats, format_stats

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
    from .library.index import load_index
    from .library.search import SearchIndex

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


@main.group()
def priors() -> None:
    """Contextual priors learned from a corpus."""


@priors.command("train")
@click.argument("source")
@click.option("-o", "--out", "out", required=True, type=click.Path(dir_okay=False), help="Priors file (.npz).")
@meshes_option
@click.option("--json", "as_json", is_flag=True)
def priors_train_cmd(source: str, out: str, meshes: str | None, as_json: bool) -> None:
    """Learn the occurrence, surface, attachment, position and orientation priors of SOURCE."""
    import time

    from .learning.priors import Priors

    c = _load(source, meshes)
    started = time.perf_counter()
    learned = Priors.fit(c.scenes, c.taxonomy, progress=progress)
    path = learned.save(out)
    info = {"out": str(path), "bytes": path.stat().st_size, "train_s": time.perf_counter() - started,
            **learned.describe()}
    emit(info, as_json, f"trained on {info['scenes']} scenes ({info['supports']} supports, {info['pairs']} pairs) "
                        f"in {info['train_s']:.1f} s → {path} ({info['bytes'] / 1e6:.1f} MB)")


def _triple(ctx, param, value):
    if value is None:
        return None
    parts = value.split(",")
    try:
        numbers = tuple(float(p) for p in parts)
    except ValueError:
        raise click.BadParameter(f"expected X,Y,Z numbers, got {value!r}") from None
    if len(numbers) != 3:
        raise click.BadParameter(f"expected three comma-separated numbers, got {len(numbers)}")
    return numbers


def _engine(name: str, trained: str, frames: bool = False, **paper_options):
    """The engine ``name`` answering from ``trained`` (a priors file, or the learned engine's file); ``frames``: the
    learned engine turning by its frame classifier."""
    from .engines import configure, load
    from .engines.protocol import LoadContext

    if name == "http":
        raise SceneSuggestError("the http engine answers for a study: name it in a study file's condition",
                                field="engine")
    options = {k: v for k, v in paper_options.items() if v}
    if options and name != "paper":
        raise SceneSuggestError(f"--{next(iter(options)).replace('_', '-')} is an option of the paper engine",
                                field="engine")
    if frames and name != "learned":
        raise SceneSuggestError("--frames is an option of the learned engine", field="engine")
    if name == "learned":
        options = {"file": trained, "frames": frames}
    return load(configure({"name": name, **options}), LoadContext(Path(trained)))


@main.command("suggest")
@click.option("--priors", "priors_file", required=True, type=click.Path(dir_okay=False),
              help="The engine's trained file: priors (paper, frequency) or the learned engine's file.")
@click.option("--engine", "engine_name", default="paper", show_default=True,
              help="A registered engine (scenesuggest engine list).")
@click.option("--scene", "scene_file", required=True, type=click.Path(dir_okay=False), help="Native scene JSON.")
@click.option("--parent", "parent_id", required=True, help="Id of the clicked object.")
@click.option("--point", required=True, callback=_triple, help="Clicked point X,Y,Z (metres, world frame).")
@click.option("--normal", required=True, callback=_triple, help="Surface normal X,Y,Z at the point.")
@click.option("--mode", type=click.Choice(["basic", "full"]), default="full", show_default=True)
@click.option("--top", default=10, show_default=True, type=click.IntRange(min=1))
@click.option("--scene-type", default=None, help="Override the scene's type.")
@click.option("--infer-scene-type", is_flag=True, help="Infer the scene type from the objects present.")
@click.option("--collision-aware", is_flag=True, help="Turn or penalise categories that do not fit (paper).")
@click.option("--refine-anchor", is_flag=True, help="Move each placement to a nearby more typical spot (paper).")
@click.option("--frames", is_flag=True, help="Turn each suggestion as the frame classifier chooses (learned).")
@click.option("--explain", is_flag=True, help="Say why each category got its rank.")
@click.option("--category", "explain_categories", multiple=True,
              help="With --explain: also explain this category wherever it ranks (repeatable).")
@click.option("--json", "as_json", is_flag=True)
def suggest_cmd(priors_file, engine_name, scene_file, parent_id, point, normal, mode, top, scene_type,
                infer_scene_type, collision_aware, refine_anchor, frames, explain, explain_categories, as_json) -> None:
    """Rank categories for a click on a surface, each with a placement (column-major 4×4)."""
    from .evaluation.formatting import explanation_lines
    from .scenes import scene_json
    from .suggestion.suggest import ContextQuery

    engine = _engine(engine_name, priors_file, frames, collision_aware=collision_aware,
                     anchor_refinement=refine_anchor, infer_scene_type=infer_scene_type)
    query = ContextQuery(scene_json.load(scene_file), parent_id, point, normal, scene_type)
    found = engine.suggest(query, mode, top)
    data = {"mode": mode, **found.to_dict()}
    lines = [f"{found.surface_type} of {found.parent_category} in a {found.scene_type} ({mode} mode, the "
             f"{found.engine} engine)"]
    for x in found:
        t = x.placement[:3, 3]
        terms = " ".join(f"{k[:3]} {v:.2f}" for k, v in x.terms.items())
        lines.append(f"{x.rank:>3}. {x.category:<22} {x.score:7.3f}  {terms}  {x.attachment_face:<6} "
                     f"{x.heading_deg:5.0f}°  at ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f})  {x.models[0]}"
                     + (f"  [{'; '.join(x.notes)}]" if x.notes else ""))
    if explain:
        if collision_aware or refine_anchor:
            raise SceneSuggestError("explanations are of the engine's own ranking, without --collision-aware or "
                                    "--refine-anchor", field="explain")
        if not hasattr(engine, "explain"):
            raise SceneSuggestError(f"the {engine_name!r} engine gives no explanations", field="explain")
        unknown = [c for c in explain_categories if c not in engine.categories]
        if unknown:
            raise SceneSuggestError(f"the engine has no category {unknown[0]!r}", field="category")
        data["explanations"] = engine.explain(query, mode, top, explain_categories)
        lines += explanation_lines(data["explanations"])
    emit(data, as_json, "\n".join(lines))


@main.command("evaluate")
@click.argument("source", required=False)
@click.option("--train", "train_source", default=None,
              help="Train every engine on all of this corpus and ask another's queries (with --test).")
@click.option("--test", "test_source", default=None,
              help="The corpus asked, its categories mapped into --train's through WordNet (with --train).")
@click.option("--explain", "explain", default=0, show_default=True, type=click.IntRange(min=0),
              help="With --train/--test: each explaining engine's N worst misses, with why.")
@click.option("--like-for-like/--no-like-for-like", default=True, show_default=True,
              help="With --train/--test: also each engine's in-corpus MRR on --train reweighted to --test's "
                   "category mix, and its ceiling: the engine trained by grouped folds on --test itself (every "
                   "engine trained twice more, k-fold; slow).")
@click.option("--folds", default=5, show_default=True, type=click.IntRange(min=2))
@click.option("--seed", default=0, show_default=True)
@click.option("--engine", "engine_names", multiple=True,
              help="A registered engine to evaluate (repeat to compare; default: paper). The first is the reference "
                   "of the paired comparison.")
@click.option("--resamples", default=1000, show_default=True, type=click.IntRange(min=10),
              help="Bootstrap resamples of the paired MRR differences.")
@click.option("--group-similar/--no-group-similar", default=True, show_default=True,
              help="Keep near-copies of a scene in one fold (and report plain k-fold figures beside).")
@click.option("--scene-type", "scene_type", type=click.Choice(["inferred", "given"]), default="inferred",
              show_default=True, help="A query's room type: inferred from the objects left once the queried one "
                                      "is removed (as a participant's scene gives it), or 'given': the scene's own "
                                      "(Stanford's was inferred from every object, the queried one too: it leaks).")
@click.option("--by-category", is_flag=True, help="Also print orientation and MRR per category.")
@click.option("--ablations", is_flag=True, help="Also train and measure each orientation ablation (slow).")
@meshes_option
@click.option("--json", "as_json", is_flag=True)
def evaluate_cmd(source: str | None, train_source: str | None, test_source: str | None, explain: int,
                 like_for_like: bool, folds: int, seed: int, engine_names: tuple[str, ...], resamples: int,
                 group_similar: bool, scene_type: str, by_category: bool, ablations: bool, meshes: str | None,
                 as_json: bool) -> None:
    """Held-out MRR, top-1/top-5 and orientation accuracy, k-fold by scene, with baselines; with several
    --engine, every engine on the same folds with paired intervals of the MRR differences. With --train and
    --test instead of SOURCE: trained on one corpus, asked on another."""
    from .engines import configure, kind
    from .evaluation.evaluate import check_evaluable, evaluate
    from .evaluation.formatting import format_evaluation

    for name in engine_names:  # before the options: an engine that needs some (http) is not evaluable anyway
        if not (kind(name).trainable or hasattr(kind(name), "from_priors")):
            raise SceneSuggestError(f"the {name!r} engine is not trained by this project, so it cannot be "
                                    "evaluated on held-out folds", field="engine")
    specs = [configure({"name": name}) for name in engine_names or ("paper",)]
    check_evaluable(specs)
    if (train_source is None) != (test_source is None):
        raise SceneSuggestError("--train and --test go together", field="train" if train_source is None else "test")
    if train_source is not None:
        if source is not None:
            raise SceneSuggestError("give SOURCE or --train and --test, not both", field="source")
        if ablations or by_category or _given("group_similar"):
            raise SceneSuggestError("--ablations, --by-category and --group-similar are of one corpus's folds, not "
                                    "--train/--test", field="train")
        _transfer(train_source, test_source, specs, folds, seed, resamples, scene_type, like_for_like, explain,
                  meshes, as_json)
        return
    if source is None:
        raise SceneSuggestError("name the corpus to evaluate (SOURCE), or --train and --test", field="source")
    if _given("explain") or _given("like_for_like"):
        raise SceneSuggestError("--explain and --like-for-like are of --train/--test", field="explain")
    c = _load(source, meshes)
    if len(c.scenes) < folds:
        raise SceneSuggestError(f"{len(c.scenes)} scenes cannot make {folds} folds", field="folds")
    result = evaluate(c, folds=folds, seed=seed, progress=progress, group_similar=group_similar,
                      ablations=ablations, engines=specs, resamples=resamples, scene_type=scene_type)
    emit(result, as_json, format_evaluation(result, by_category=by_category))


def _given(parameter: str) -> bool:
    """Whether the command line gave ``parameter`` (even at its default value)."""
    ctx = click.get_current_context()
    if parameter not in ctx.params:
        raise RuntimeError(f"the command has no parameter {parameter!r}")
    source = ctx.get_parameter_source(parameter)
    return source is not None and source.name == "COMMANDLINE"


def _transfer(train_source: str, test_source: str, specs, folds: int, seed: int, resamples: int, scene_type: str,
              like_for_like: bool, explain: int, meshes: str | None, as_json: bool) -> None:
    from .corpora.wordnet import wordnet
    from .evaluation.formatting import format_transfer
    from .evaluation.transfer import evaluate_transfer

    wordnet()  # before the corpora load: say at once that WordNet is missing
    train, test = _load(train_source, meshes), _load(test_source, meshes)
    result = evaluate_transfer(train, test, specs, seed=seed, resamples=resamples, scene_type=scene_type, folds=folds,
                               like_for_like=like_for_like, explain=explain, progress=progress)
    emit(result, as_json, format_transfer(result))


if __name__ == "__main__":  # pragma: no cover
    main()
