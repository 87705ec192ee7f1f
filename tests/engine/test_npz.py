"""Priors and engine files are read with every member checked before it takes memory: a small file that would
expand to gigabytes, or whose array headers say more than its members hold, is an error naming it."""

import json
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from scenesuggest.errors import SceneSuggestError
from scenesuggest.learning.priors import Priors
from scenesuggest.npz import EPOCH, MIN_BUDGET, npz_bytes, read_npz

META = np.frombuffer(json.dumps({"format": "scenesuggest-priors"}).encode(), dtype=np.uint8)


def bomb(path, megabytes: int) -> None:
    """An .npz of a metadata member and ``megabytes`` MB of zeros: a few hundred kB on disk."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as z:
        with z.open(zipfile.ZipInfo("meta.npy", date_time=EPOCH), "w") as f:
            np.lib.format.write_array(f, META)
        info = zipfile.ZipInfo("alpha_n.npy", date_time=EPOCH)
        info.compress_type = zipfile.ZIP_DEFLATED
        with z.open(info, "w", force_zip64=True) as f:
            np.lib.format.write_array_header_2_0(f, {"descr": "<u4", "fortran_order": False,
                                                     "shape": (megabytes << 18,)})
            zeros = bytes(1 << 20)
            for _ in range(megabytes):
                f.write(zeros)


def test_what_npz_bytes_writes_reads_back_the_same(tmp_path):
    arrays = {"a": np.arange(12, dtype=np.float32).reshape(3, 4), "b": np.zeros((0, 2)), "c": np.array(3.5),
              "d": np.asfortranarray(np.arange(6).reshape(2, 3))}
    path = tmp_path / "x.npz"
    path.write_bytes(npz_bytes(arrays))
    back = read_npz(path)
    assert set(back) == set(arrays)
    for name, a in arrays.items():
        assert back[name].dtype == a.dtype and back[name].shape == a.shape and np.array_equal(back[name], a)
    assert set(read_npz(path, ("a",))) == {"a"}


def test_a_small_file_expanding_to_hundreds_of_megabytes_is_refused_before_it_takes_memory(tmp_path):
    """A priors file of a few hundred kB holding 512 MB of zeros: refused from the zip's directory, in a process
    whose memory stays far below what numpy.load would take."""
    path = tmp_path / "bomb.npz"
    bomb(path, 512)
    assert path.stat().st_size < 2 << 20
    probe = ("import resource, sys\nfrom scenesuggest.errors import SceneSuggestError\n"
             "from scenesuggest.learning.priors import Priors\n"
             "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
             "try:\n    Priors.load(sys.argv[1])\nexcept SceneSuggestError as e:\n    print(e)\n"
             "print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) // 1024)\n")
    done = subprocess.run([sys.executable, "-c", probe, str(path)], capture_output=True, text=True, timeout=120)
    said, grew_mb = done.stdout.strip().splitlines()
    assert said.startswith(f"{path}: cannot read priors: its arrays would take") and "not a file this project" in said
    assert int(grew_mb) < 64, grew_mb  # numpy.load takes the 512 MB (and more) before anything can refuse


def test_a_header_saying_more_than_its_member_holds_is_refused(tmp_path):
    """A member whose .npy header claims a billion items in a few bytes never gets them allocated."""
    path = tmp_path / "liar.npz"
    with zipfile.ZipFile(path, "w") as z, z.open(zipfile.ZipInfo("sample_xy.npy", date_time=EPOCH), "w") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (10**9, 2)})
        f.write(bytes(16))
    with pytest.raises(SceneSuggestError, match=r"member 'sample_xy.npy' says \(1000000000, 2\) of float64") as info:
        read_npz(path)
    assert info.value.file == str(path)


@pytest.mark.parametrize("content", [b"", b"not a zip at all", b"PK\x03\x04" + bytes(40)])
def test_a_file_that_is_no_npz_is_an_error_naming_it(tmp_path, content):
    path = tmp_path / "priors.npz"
    path.write_bytes(content)
    with pytest.raises(SceneSuggestError, match="cannot read priors") as info:
        Priors.load(path)
    assert info.value.file == str(path)


def test_objects_are_refused(tmp_path):
    path = tmp_path / "objects.npz"
    with zipfile.ZipFile(path, "w") as z, z.open(zipfile.ZipInfo("meta.npy", date_time=EPOCH), "w") as f:
        np.lib.format.write_array(f, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(SceneSuggestError, match="Python objects"):
        read_npz(path)


def test_the_budget_lets_through_what_the_project_writes(tmp_path):
    """Count arrays of zeros expand about 300 to 1; a whole file within its budget reads."""
    counts = np.zeros((400, 6, 6, 36), dtype=np.uint16)
    counts[::7, 0, 0, ::9] = 3
    path = tmp_path / "counts.npz"
    path.write_bytes(npz_bytes({"alpha_n": counts}))
    assert counts.nbytes < MIN_BUDGET and np.array_equal(read_npz(path)["alpha_n"], counts)
