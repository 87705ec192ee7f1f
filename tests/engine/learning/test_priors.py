"""The priors, on a synthetic corpus whose statistics are known by construction."""

import inspect
import re

import numpy as np
import pytest

from scenesuggest.errors import SceneSuggestError
from scenesuggest.learning.orientation import BINS, KINDS
from scenesuggest.learning.priors import K_MAX, Priors
from scenesuggest.scenes.frames import FACES
from scenesuggest.scenes.scene import SURFACE_TYPES


@pytest.fixture(scope="module")
def priors(corpus):
    return Priors.fit(corpus.scenes, corpus.taxonomy)


def occurrence(priors, parent, child, scene_type):
    key = priors.occurrence_key(parent, scene_type)
    children, rows = priors.occurrence_rows(key)
    e = priors.entity_index[child]
    return rows[list(children).index(e)] if e in children else np.zeros(K_MAX + 1)


def test_occurrence_is_the_tail_of_the_child_count_histogram(priors):
    speakers = occurrence(priors, "Desk", "Speaker", "Study")
    assert speakers[:3] == pytest.approx([1.0, 1.0, 0.0])  # every desk has exactly two speakers
    monitors = occurrence(priors, "Desk", "Monitor", "Study")
    assert monitors[:2] == pytest.approx([1.0, 0.0])
    books = occurrence(priors, "Nightstand", "Book", "Bedroom")
    assert books[:2] == pytest.approx([0.5, 0.0])  # every other nightstand carries a book
    assert occurrence(priors, "Nightstand", "Monitor", "Bedroom")[0] == 0.0


def test_surface_and_attachment_counts(priors):
    e = priors.entity_index["Poster"]
    assert priors.sup_counts[e, SURFACE_TYPES.index("vertical_interior")] == 12
    t = SURFACE_TYPES.index("up_exterior")
    assert priors.att_counts[priors.entity_index["Monitor"], t, 0] == 12  # "bottom" is the first face


def test_back_off_to_the_subtree_below_five_instances(priors):
    assert priors.entities[priors.stat_entity("Monitor")] == "Monitor"  # 12 instances
    # keyed by scene type, a nightstand in a study climbs to all tables (desks) in studies ...
    e, s = priors.keyed_entity("Nightstand", "Study")
    assert (priors.entities[e], priors.scene_types[s]) == ("Table/*", "Study")
    assert priors.scene_types[priors.keyed_entity("Nightstand", "Bedroom")[1]] == "Bedroom"
    # ... while a poster in a bedroom finds no wall art there and reads all scene types
    e, s = priors.keyed_entity("Poster", "Bedroom")
    assert (priors.entities[e], priors.scene_types[s]) == ("Poster", "*")
    assert priors.keyed_entity("Poster", "Bedroom", backoff=False) == (priors.entity_index["Poster"],
                                                                         priors.scene_index["Bedroom"])


def test_back_off_climbs_the_taxonomy(corpus):
    from scenesuggest.scenes.taxonomy import Taxonomy

    # four books: fewer than five, so a book reads the statistics of everything on a nightstand's top
    tax = Taxonomy({"Book": "TableTop", "DeskLamp": "TableTop"})
    p = Priors.fit(corpus.scenes, tax)
    assert p.occ_parent_n[p.entity_index["Book"], -1] == 4
    assert p.entities[p.stat_entity("Book")] == "TableTop/*"
    assert p.occ_parent_n[p.entity_index["TableTop/*"], -1] == 12
    assert p.entities[p.stat_entity("Book", backoff=False)] == "Book"


def test_position_densities_are_peak_normalised(priors):
    g = priors.group_for("Desk", "Study", "parent", "up_exterior")
    children, segs = priors.segments(g)
    seg = segs[list(children).index(priors.entity_index["Monitor"])]
    a, n = priors.seg_start[seg], priors.seg_count[seg]
    pts = priors.pair_xy[a:a + n].astype(float)
    bw = priors.seg_bandwidth[seg].astype(float)
    dens = lambda x: priors.seg_weight[seg] * np.exp(-0.5 * (((x - pts) / bw) ** 2).sum(axis=1)).sum()  # noqa: E731
    assert max(dens(p) for p in pts) == pytest.approx(1.0, rel=1e-5)
    assert pts.mean(axis=0) == pytest.approx([0.0, -0.2], abs=0.02)  # 20 cm behind the desk's centre
    assert bw.min() >= 0.05 - 1e-7


def test_chairs_face_their_desks(priors):
    g = priors.group_for("Desk", "Study", "sibling", "up_interior")
    children, segs = priors.segments(g)
    seg = segs[list(children).index(priors.entity_index["OfficeChair"])]
    assert int(np.argmax(priors.seg_hist[seg])) == 18  # 180°: the chair's front faces the desk's front


def test_save_load_is_byte_stable(priors, tmp_path):
    first = priors.save(tmp_path / "a.npz")
    loaded = Priors.load(first)
    second = loaded.save(tmp_path / "b.npz")
    assert first.read_bytes() == second.read_bytes()
    assert loaded.describe() == priors.describe()


def test_files_from_other_versions_and_garbage_are_refused(priors, tmp_path):
    import json

    path = priors.save(tmp_path / "p.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(arrays["meta"].tobytes())
    meta["version"] = 99
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez_compressed(tmp_path / "old.npz", **arrays)
    with pytest.raises(SceneSuggestError) as info:
        Priors.load(tmp_path / "old.npz")
    assert info.value.field == "version" and "retrain" in str(info.value)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(SceneSuggestError, match="cannot read priors"):
        Priors.load(tmp_path / "junk.npz")


def documented_attributes() -> dict[str, tuple[list[str], str]]:
    """name → (dimensions, dtype) of each entry of the Attributes section of the Priors docstring."""
    lines = inspect.cleandoc(Priors.__doc__).splitlines()
    start = lines.index("Attributes") + 1
    assert set(lines[start]) == {"-"}
    out = {}
    for line in lines[start + 1:]:
        if not line or line.startswith(" "):
            continue
        if not re.match(r"\w+ : ", line):
            break  # the end of the section
        m = re.fullmatch(r"(\w+) : ndarray of shape \((.*)\), (\w+)", line)
        assert m, f"not 'name : ndarray of shape (...), dtype': {line!r}"
        out[m[1]] = ([d.strip() for d in m[2].split(",") if d.strip()], m[3])
    return out


def test_every_learned_array_is_declared_with_its_shape(priors, tmp_path):
    documented = documented_attributes()
    with np.load(priors.save(tmp_path / "p.npz")) as data:
        saved = set(data.files) - {"meta"}
    assert saved == set(documented) == set(Priors.ARRAY_NAMES)
    known = {"entities": len(priors.entities), "scene types": len(priors.scene_types),
             "surface types": len(SURFACE_TYPES), "faces": len(FACES), "BINS": BINS, "K_MAX + 1": K_MAX + 1,
             "kinds": len(KINDS), "models": len(priors.model_ids)}
    free: dict[str, int] = {}  # rows, groups, segments, samples, candidates: the same wherever they appear
    for name, (dims, dtype) in documented.items():
        array = getattr(priors, name)
        assert array is priors.arrays[name]
        assert array.dtype == np.dtype(dtype), name
        assert array.ndim == len(dims), name
        for dim, size in zip(dims, array.shape, strict=True):
            expected = int(dim) if dim.isdigit() else known[dim] if dim in known else free.setdefault(dim, size)
            assert size == expected, f"{name}: {dim} is {size}, expected {expected}"
    assert set(free) == {"rows", "groups", "segments", "samples", "candidates"} and min(free.values()) > 0
