"""Arrays as ``.npz`` bytes that depend on the arrays only: entries in name order, each stamped with one fixed
date (numpy's own writer stamps the current time, so two saves of the same arrays could differ); and such a file
read back with every member checked before it takes memory (:func:`read_npz`).

A priors or engine file is code-like (it decides what participants are shown), so it should come from a trusted
source; still, a damaged or hostile one must end in an error naming it, never in an allocation of gigabytes: a
zip member of zeros compresses a thousand to one. The project's files expand about 16 to 1 overall (the count
arrays, mostly zeros, up to 300 to 1 each), so a file may hold at most MAX_EXPANSION times its size on disk in
arrays (and any file MIN_BUDGET), and each member's ``.npy`` header must describe exactly the bytes the zip
directory declares for it.
"""

from __future__ import annotations

import io
import math
import zipfile
from collections.abc import Collection
from pathlib import Path

import numpy as np

from .errors import SceneSuggestError

#: The date every entry carries (the earliest a zip file can hold).
EPOCH = (1980, 1, 1, 0, 0, 0)
#: The most the arrays of a file may take in memory: MAX_EXPANSION times its size on disk (three times the most a
#: trained file of the project has needed), and MIN_BUDGET bytes whatever its size.
MAX_EXPANSION = 48
MIN_BUDGET = 64 << 20


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """A compressed ``.npz`` of ``arrays`` (name → array; no pickled objects), readable by ``numpy.load``."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            with z.open(info, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.asanyarray(arrays[name]), allow_pickle=False)
    return buffer.getvalue()


def read_npz(path: str | Path, only: Collection[str] | None = None, what: str = "") -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file (name → array; ``only``: just these names), each member checked before memory
    is taken for it (see the module docstring): stored as ``.npy``, no Python objects, its header's shape and type
    exactly its declared size, and all of them within the file's budget. Anything else is a
    :class:`SceneSuggestError` naming the file (and the member), its message begun ``cannot read WHAT:`` when
    ``what`` names the file's kind."""
    try:
        return _read(Path(path), only)
    except SceneSuggestError as e:
        if what:
            raise SceneSuggestError(f"cannot read {what}: {e.message}", file=e.file, field=e.field) from None
        raise


def _read(path: Path, only: Collection[str] | None) -> dict[str, np.ndarray]:
    try:
        with zipfile.ZipFile(path) as z:
            infos = [i for i in z.infolist() if only is None or i.filename.removesuffix(".npy") in only]
            budget = max(MIN_BUDGET, MAX_EXPANSION * path.stat().st_size)
            declared = sum(i.file_size for i in infos)
            if declared > budget:
                raise SceneSuggestError(f"its arrays would take {declared:,} bytes, more than {budget:,} "
                                        f"({MAX_EXPANSION} times its size): not a file this project wrote",
                                        file=str(path))
            return {i.filename.removesuffix(".npy"): _member(z, i, path) for i in infos}
    except SceneSuggestError:
        raise
    except Exception as e:  # noqa: BLE001 - zlib, the .npy header's parser, zipfile: any damage is the file's
        raise SceneSuggestError(f"not a readable .npz file ({type(e).__name__}: {e})", file=str(path)) from None


def _member(z: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path) -> np.ndarray:
    def refuse(why: str) -> SceneSuggestError:
        return SceneSuggestError(f"member {info.filename!r} {why}", file=str(path), field=info.filename)

    if not info.filename.endswith(".npy") or info.is_dir():
        raise refuse("is not an array (.npy)")
    with z.open(info) as f:  # zipfile reads at most the declared size, and checks it and the CRC at the end
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise refuse(f"has a .npy header of version {version}")
        if dtype.hasobject:
            raise refuse("holds Python objects")
        need = math.prod(shape) * dtype.itemsize
        if need != info.file_size - f.tell():
            raise refuse(f"says {shape} of {dtype} ({need:,} bytes) in {info.file_size - f.tell():,} bytes")
        data = bytearray(need)
        view, got = memoryview(data), 0
        while got < need:
            n = f.readinto(view[got:])
            if not n:
                raise refuse("ends early")
            got += n
        if f.read(1):
            raise refuse("holds more than its header says")
    return np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C")
