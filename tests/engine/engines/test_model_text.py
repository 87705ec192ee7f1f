"""A learned engine's file whose LightGBM models are damaged is refused with a message, never an abort."""

import subprocess
import sys

import numpy as np
import pytest
import synthetic

from scenesuggest.engines.learned import LearnedEngine
from scenesuggest.engines.learned.features import ORIENTATION, RANKING
from scenesuggest.engines.learned.model_text import check_model_text
from scenesuggest.errors import SceneSuggestError
from scenesuggest.npz import npz_bytes


def payload_of(path):
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def damaged(path, tmp_path, change):
    """The file with its ranker's text changed by ``change`` (text → text), written beside."""
    payload = payload_of(path)
    text = change(payload["ranker"].tobytes().decode())
    payload["ranker"] = np.frombuffer(text.encode(), dtype=np.uint8)
    out = tmp_path / "damaged.npz"
    out.write_bytes(npz_bytes(payload))
    return out


def first_line(text, key, change, where=lambda value: True):
    """``text`` with the first ``key=`` line whose value satisfies ``where`` changed by ``change`` (value → value)."""
    lines = text.split("\n")
    i = next(k for k, line in enumerate(lines) if line.startswith(key + "=") and where(line.split("=", 1)[1]))
    lines[i] = key + "=" + change(lines[i].split("=", 1)[1])
    return "\n".join(lines)


def test_the_models_a_training_writes_pass_the_check(learned_file):
    payload = payload_of(learned_file)
    check_model_text(payload["ranker"].tobytes().decode(), len(RANKING))
    if "frames" in payload:
        check_model_text(payload["frames"].tobytes().decode(), len(ORIENTATION))


@pytest.mark.parametrize(("change", "words"), [
    (lambda t: first_line(t, "split_feature", lambda v: " ".join(["999"] * len(v.split()))), "tree 0"),
    (lambda t: first_line(t, "split_feature", lambda v: " ".join(["9" * len(x) for x in v.split()]),
                          where=lambda v: any(len(x) > 1 for x in v.split())),  # 99: beyond the features
     "a split on a feature outside"),
    (lambda t: first_line(t, "left_child", lambda v: " ".join(x.replace("1", "7") for x in v.split())), "tree 0"),
    (lambda t: first_line(t, "tree_sizes", lambda v: " ".join(str(int(x) + 1) for x in v.split())), "tree"),
    (lambda t: first_line(t, "max_feature_idx", lambda v: "2"), "features"),
    (lambda t: t.replace("version=v4", "version=v9"), "v4"),
])
def test_a_damaged_model_is_refused_naming_the_file_and_model(learned_file, tmp_path, change, words):
    bad = damaged(learned_file, tmp_path, change)
    with pytest.raises(SceneSuggestError, match=words) as info:
        LearnedEngine.load(bad)
    assert info.value.file == str(bad) and info.value.field == "ranker"


def test_the_damage_that_aborted_the_process_is_now_a_cli_error(learned_file, tmp_path):
    """A changed split_feature line moves every later tree off its tree_sizes: LightGBM itself aborts (SIGABRT)."""
    bad = damaged(learned_file, tmp_path, lambda t: first_line(
        t, "split_feature", lambda v: " ".join(["999"] * len(v.split()))))
    raw = subprocess.run([sys.executable, "-c", "import sys, numpy as np, lightgbm as lgb; "
                          "d = np.load(sys.argv[1]); lgb.Booster(model_str=d['ranker'].tobytes().decode())",
                          str(bad)], capture_output=True, text=True)
    assert raw.returncode != 0  # what LightGBM does with it unchecked
    scene = synthetic.corpus().scenes[0]
    from scenesuggest.scenes import scene_json

    scene_file = tmp_path / "scene.json"
    scene_json.save(scene, scene_file)
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "suggest", "--engine", "learned", "--priors",
                           str(bad), "--scene", str(scene_file), "--parent", "room", "--point", "1,0,1",
                           "--normal", "0,1,0"], capture_output=True, text=True)
    assert proc.returncode == 2 and "ranker model is damaged" in proc.stderr and str(bad) in proc.stderr
