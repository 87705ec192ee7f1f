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
