"""The scenesuggest command, run as a user would (a subprocess with the installed entry point)."""

import json
import subprocess
import sys


def run(*args, check=True):
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", *args], capture_output=True, text=True)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def test_corpus_stats_stanford_json(stanford_dir):
    stats = json.loads(run("corpus", "stats", f"stanford:{stanford_dir}", "--json").stdout)
    assert stats["scenes"] == 133 and stats["objects"] == 3594
    for key in ("scene_types", "categories", "parent_categories", "surface_types", "attachment_faces"):
        assert isinstance(stats[key], dict) and stats[key]
    assert sum(stats["surface_types"].values()) == 3594 - 133


def test_corpus_stats_ai2thor_json_and_human():
    stats = json.loads(run("corpus", "stats", "ai2thor", "--json").stdout)
    assert stats["scenes"] == 195 and stats["scene_types"]["Kitchen"] >= 30
    human = run("corpus", "stats", "ai2thor").stdout
    assert "195 scenes" in human and "Support parents" in human


def test_search_command():
    out = json.loads(run("search", "alarm clock", "--json").stdout)
    assert out["hits"][0]["category"] == "AlarmClock"


def test_bad_source_is_a_clear_error():
    proc = run("corpus", "stats", "nowhere:/x", check=False)
    assert proc.returncode == 2 and "unknown corpus source" in proc.stderr and "Traceback" not in proc.stderr
    proc = run("corpus", "stats", "stanford:/does/not/exist", check=False)
    assert proc.returncode == 2 and "no such folder" in proc.stderr


def test_malformed_scene_file_names_file_and_line(tmp_path):
    scenes = tmp_path / "db" / "scenes"
    scenes.mkdir(parents=True)
    (scenes / "scene00000.txt").write_text("StanfordSceneDatabase\nversion 1.0\nmodelCount 1\nnewModel 0 room01\n"
                                           "parentIndex -1\nscale 1.0.0\n")
    proc = run("corpus", "stats", f"stanford:{tmp_path / 'db'}", check=False)
    assert proc.returncode == 2
    assert "scene00000.txt:6: field 'scale': bad number '1.0.0'" in proc.stderr


def test_priors_train_and_suggest(tmp_path):
    import synthetic

    from scenesuggest.corpora.native import write_native

    corpus_dir = write_native(synthetic.corpus(), tmp_path / "corpus")
    info = json.loads(run("priors", "train", f"json:{corpus_dir}", "-o", str(tmp_path / "p.npz"), "--json").stdout)
    assert info["scenes"] == 20 and info["bytes"] == (tmp_path / "p.npz").stat().st_size
    scene = corpus_dir / "scenes" / "study00.json"
    doc = json.loads(scene.read_text())
    desk = next(o for o in doc["objects"] if o["category"] == "Desk")
    x, _, z = desk["transform"][12:15]
    args = ["suggest", "--priors", str(tmp_path / "p.npz"), "--scene", str(scene), "--parent", desk["id"],
            "--point", f"{x},0.75,{z - 0.2}", "--normal", "0,1,0"]
    out = json.loads(run(*args, "--json", "--top", "3").stdout)
    assert out["surface_type"] == "up_exterior" and out["scene_type"] == "Study"
    assert len(out["suggestions"]) == 3
    first = out["suggestions"][0]
    assert {"category", "score", "terms", "placement", "attachment_face", "models"} <= set(first)
    assert len(first["placement"]) == 16
    human = run(*args, "--mode", "basic", "--collision-aware").stdout
    assert "up_exterior of Desk in a Study (basic mode, the paper engine)" in human


def test_suggest_errors_are_clear(tmp_path):
    import synthetic

    from scenesuggest.corpora.native import write_native

    corpus_dir = write_native(synthetic.corpus(n_study=3, n_bedroom=2), tmp_path / "corpus")
    run("priors", "train", f"json:{corpus_dir}", "-o", str(tmp_path / "p.npz"))
    base = ["suggest", "--priors", str(tmp_path / "p.npz"), "--scene", str(corpus_dir / "scenes" / "study00.json")]
    bad = run(*base, "--parent", "ghost", "--point", "0,0,0", "--normal", "0,1,0", check=False)
    assert bad.returncode == 2 and "field 'parent'" in bad.stderr and "Traceback" not in bad.stderr
    bad = run(*base, "--parent", "room", "--point", "0,0", "--normal", "0,1,0", check=False)
    assert bad.returncode == 2 and "--point" in bad.stderr
    bad = run(*base, "--parent", "room", "--point", "0,0,0", "--normal", "0,0,0", check=False)
    assert bad.returncode == 2 and "field 'normal'" in bad.stderr
    (tmp_path / "old.npz").write_bytes(b"garbage")
    bad = run("suggest", "--priors", str(tmp_path / "old.npz"), "--scene", str(corpus_dir / "scenes" / "study00.json"),
              "--parent", "room", "--point", "0,0,0", "--normal", "0,1,0", check=False)
    assert bad.returncode == 2 and "cannot read priors" in bad.stderr


def test_engine_train_cli(tmp_path):
    """`scenesuggest engine train` writes a learned engine's file that `suggest --engine learned` reads; engines it
    cannot train, and unknown ones, are named."""
    import synthetic

    from scenesuggest.corpora.native import write_native

    corpus_dir = write_native(synthetic.corpus(), tmp_path / "corpus")
    out = tmp_path / "learned.npz"
    info = json.loads(run("engine", "train", "learned", f"json:{corpus_dir}", "-o", str(out), "--json").stdout)
    assert info["engine"] == "learned" and out.stat().st_size > 0
    scene = corpus_dir / "scenes" / "study00.json"
    desk = next(o for o in json.loads(scene.read_text())["objects"] if o["category"] == "Desk")
    x, _, z = desk["transform"][12:15]
    found = json.loads(run("suggest", "--engine", "learned", "--priors", str(out), "--scene", str(scene), "--parent",
                           desk["id"], "--point", f"{x},0.75,{z - 0.2}", "--normal", "0,1,0", "--json").stdout)
    assert found["engine"] == "learned" and found["suggestions"]
    click = ["--scene", str(scene), "--parent", desk["id"], "--point", f"{x},0.75,{z - 0.2}", "--normal", "0,1,0"]
    framed = json.loads(run("suggest", "--engine", "learned", "--frames", "--priors", str(out), *click,
                            "--json").stdout)
    assert [s["category"] for s in framed["suggestions"]] == [s["category"] for s in found["suggestions"]]
    bad = run("suggest", "--engine", "paper", "--frames", "--priors", str(out), *click, check=False)
    assert bad.returncode == 2 and "--frames is an option of the learned engine" in bad.stderr
    bad = run("engine", "train", "http", f"json:{corpus_dir}", "-o", str(tmp_path / "h.npz"), check=False)
    assert bad.returncode == 2 and "not trained by this project" in bad.stderr and not (tmp_path / "h.npz").exists()
    bad = run("engine", "train", "nope", f"json:{corpus_dir}", "-o", str(tmp_path / "n.npz"), check=False)
    assert bad.returncode == 2 and "unknown engine 'nope'" in bad.stderr
    assert "Train the engine NAME on SOURCE" in run("engine", "train", "--help").stdout
