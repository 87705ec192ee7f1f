"""Bad input in the Stanford text format: errors name file, line and field; nothing is half-imported."""

from pathlib import Path

import pytest

from scenesuggest.corpora import load_corpus
from scenesuggest.corpora.native import write_native
from scenesuggest.errors import SceneSuggestError

BLOCK = """newModel {i} {model}
parentIndex {parent}
children {children}
parentMaterialGroupIndex 0
parentTriangleIndex 0
parentUV 0 0
parentContactPosition {contact}
parentContactNormal {normal}
parentOffset 0 0 0
scale 1
transform 1 0 0 0 0 1 0 0 0 0 1 0 {tx} {ty} {tz} 1
"""


def scene_text(parents=(-1, 0, 1)) -> str:
    """A room (0), a table on its floor (1) and a cup on the table (2), inches, Z up."""
    rows = [("room01", "0 0 0", "0 0 0", (0, 0, 0)), ("tbl", "50 60 0", "0 0 1", (50, 60, 0.25)),
            ("cup", "52 61 30", "0 0 1", (52, 61, 30.25))]
    out = "StanfordSceneDatabase\nversion 1.0\nmodelCount 3\n"
    for i, ((model, contact, normal, t), parent) in enumerate(zip(rows, parents, strict=True)):
        children = " ".join(str(j) for j, p in enumerate(parents) if p == i)
        out += BLOCK.format(i=i, model=model, parent=parent, children=children, contact=contact, normal=normal,
                            tx=t[0], ty=t[1], tz=t[2])
    return out


def make_corpus(tmp_path: Path, texts: dict[str, str]) -> Path:
    root = tmp_path / "db"
    (root / "scenes").mkdir(parents=True)
    for name, text in texts.items():
        (root / "scenes" / name).write_text(text)
    return root


def line_of(text: str, needle: str, occurrence: int = 1) -> int:
    lines = [n for n, line in enumerate(text.splitlines(), start=1) if line.startswith(needle)]
    return lines[occurrence - 1]


def error_for(tmp_path, text) -> SceneSuggestError:
    root = make_corpus(tmp_path, {"scene00000.txt": scene_text(), "scene00001.txt": text})
    with pytest.raises(SceneSuggestError) as info:
        load_corpus(f"stanford:{root}")
    assert info.value.file.endswith("scene00001.txt")
    return info.value


def test_a_valid_synthetic_scene_loads(tmp_path):
    root = make_corpus(tmp_path, {"scene00000.txt": scene_text()})
    corpus = load_corpus(f"stanford:{root}")
    cup = corpus.scenes[0].objects["2"]
    assert cup.parent == "1" and cup.surface_type == "up_exterior" and cup.attachment_face == "bottom"
    assert cup.contact_point == pytest.approx((52 * 0.0254, 30 * 0.0254, -61 * 0.0254))


def test_bad_number(tmp_path):
    text = scene_text().replace("parentContactPosition 52 61 30", "parentContactPosition 52 6x1 30")
    err = error_for(tmp_path, text)
    assert err.field == "parentContactPosition" and err.line == line_of(text, "parentContactPosition", 3)
    assert "bad number '6x1'" in str(err)


def test_wrong_count(tmp_path):
    good = "transform 1 0 0 0 0 1 0 0 0 0 1 0 50 60 0.25 1"
    text = scene_text().replace(good, good.replace(" 0.25 1", " 1"))
    err = error_for(tmp_path, text)
    assert err.field == "transform" and err.line == line_of(text, "transform", 2) and "expected 16" in err.message


def test_unknown_field(tmp_path):
    text = scene_text().replace("parentOffset 0 0 0\nscale 1\ntransform 1 0 0 0 0 1 0 0 0 0 1 0 52",
                                "parentOffset 0 0 0\ncolour red\nscale 1\ntransform 1 0 0 0 0 1 0 0 0 0 1 0 52")
    err = error_for(tmp_path, text)
    assert err.field == "colour" and err.line == line_of(text, "colour") and "unknown field" in err.message


def test_missing_parent(tmp_path):
    text = scene_text(parents=(-1, 0, 7))
    err = error_for(tmp_path, text)
    assert err.field == "parentIndex" and err.line == line_of(text, "parentIndex", 3)


def test_cycle_in_support_tree(tmp_path):
    text = scene_text(parents=(-1, 2, 1))
    err = error_for(tmp_path, text)
    assert err.field == "parent" and "cycle" in err.message
    assert err.line in (line_of(text, "newModel", 2), line_of(text, "newModel", 3))


def test_model_count_mismatch(tmp_path):
    text = scene_text().replace("modelCount 3", "modelCount 4")
    err = error_for(tmp_path, text)
    assert err.field == "modelCount"


def test_nothing_is_half_imported(tmp_path):
    """A bad file anywhere fails the whole load, and conversion leaves no output behind."""
    bad = scene_text().replace("scale 1\n", "scale one\n", 1)
    root = make_corpus(tmp_path, {"scene00000.txt": scene_text(), "scene00001.txt": bad})
    out = tmp_path / "native"
    with pytest.raises(SceneSuggestError):
        write_native(load_corpus(f"stanford:{root}"), out)
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["db"]


def test_native_conversion_round_trips(tmp_path):
    root = make_corpus(tmp_path, {"scene00000.txt": scene_text()})
    corpus = load_corpus(f"stanford:{root}")
    out = write_native(corpus, tmp_path / "native")
    again = load_corpus(f"json:{out}")
    assert again.scenes[0].objects == corpus.scenes[0].objects
    assert again.taxonomy.parents == corpus.taxonomy.parents
    assert set(again.models) == set(corpus.models)
    with pytest.raises(SceneSuggestError, match="not empty"):
        write_native(corpus, out)
