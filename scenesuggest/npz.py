"""Arrays as ``.npz`` bytes that depend on the arrays only: entries in name order, each stamped with one fixed
date (numpy's own writer stamps the current time, so two saves of the same arrays could differ)."""

from __future__ import annotations

import io
import zipfile

import numpy as np

#: The date every entry carries (the earliest a zip file can hold).
EPOCH = (1980, 1, 1, 0, 0, 0)


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
