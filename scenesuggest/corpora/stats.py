"""Corpus statistics: what ``scenesuggest corpus stats`` prints."""

from __future__ import annotations

from collections import Counter

from .corpus import Corpus


def _sorted(counter: Counter) -> dict[str, int]:
    return {k: v for k, v in sorted(counter.items(), key=lambda kv: (-kv[1], str(kv[0])))}


def corpus_stats(corpus: Corpus) -> dict:
    """Counts per scene type, category (instances), parent category (support edges), surface type and
    attachment face (supported objects). Keys are part of the CLI's JSON interface."""
    scene_types, categories, parents, surface_types, faces = Counter(), Counter(), Counter(), Counter(), Counter()
    n_objects = 0
    for scene in corpus.scenes:
        scene_types[scene.scene_type] += 1
        for o in scene:
            n_objects += 1
            categories[o.category] += 1
            if o.parent is not None:
                parents[scene.objects[o.parent].category] += 1
                surface_types[o.surface_type or "unknown"] += 1
                faces[o.attachment_face or "unknown"] += 1
    return {
        "source": corpus.source,
        "scenes": len(corpus.scenes),
        "objects": n_objects,
        "models": len(corpus.models),
        "scene_types": _sorted(scene_types),
        "categories": _sorted(categories),
        "parent_categories": _sorted(parents),
        "surface_types": _sorted(surface_types),
        "attachment_faces": _sorted(faces),
    }


def format_stats(stats: dict, top: int = 15) -> str:
    """A human-readable report of :func:`corpus_stats`; long sections show their ``top`` entries."""
    lines = [f"{stats['source']}: {stats['scenes']} scenes, {stats['objects']} objects, {stats['models']} models"]
    for key, title in [("scene_types", "Scene types"), ("categories", "Categories"),
                       ("parent_categories", "Support parents"), ("surface_types", "Surface types"),
                       ("attachment_faces", "Attachment faces")]:
        section = stats[key]
        lines.append("")
        lines.append(f"{title} ({len(section)})")
        width = max((len(k) for k in list(section)[:top]), default=0)
        for name, n in list(section.items())[:top]:
            lines.append(f"  {name:<{width}}  {n:>6}")
        if len(section) > top:
            lines.append(f"  … {len(section) - top} more (use --json for all)")
    return "\n".join(lines)
