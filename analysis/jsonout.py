"""JSON for results: NaN and infinity become null, numpy scalars plain numbers."""

from __future__ import annotations

import json
import math

import numpy as np


def _finite(value):
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def dumps(data, indent: int | None = 1) -> str:
    return json.dumps(_finite(data), indent=indent)
