"""How many participants a study needs, from the calibrated simulator (``scenesuggest study power``).

For each of the calibration's plausible parameter sets (:func:`.calibrate.read_plausible`: the best fit first,
then sets the paper's ``none`` numbers fit almost as well — the calibration's uncertainty), a pilot of simulated
participants takes the study in process on a database of its own; :func:`analysis.power.power` then resamples
that pilot into studies of each size and counts how often each hypothesis' likelihood-ratio test rejects. The
participants needed for a power are the smallest size that reaches it, per parameter set, so the answer comes
as the best fit's figure with the range over the plausible sets.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

#: The paper's hypotheses as tests of condition: name → (measure, conditions compared).
HYPOTHESES = {
    "H1 total time (none, basic, full)": ("total_time", ["none", "basic", "full"]),
    "H2 rotation time (full vs basic)": ("rotation_time", ["basic", "full"]),
}
TARGET_POWER = 0.8


def needed(power_by_size: dict[int, float], target: float = TARGET_POWER) -> int | None:
    """The smallest size whose power reaches ``target`` (None: none of them does)."""
    return next((n for n in sorted(power_by_size) if power_by_size[n] >= target), None)


def study_power(study_id: str, humans: list, sizes: list[int], studies: int, pilot: int, seed: int = 0,
                alpha: float = 0.05, progress: Callable[[str], None] = lambda message: None) -> dict:
    """Power of each of HYPOTHESES at each of ``sizes`` for every parameter set of ``humans`` (the best first),
    from a pilot of ``pilot`` simulated participants each; the studies configured by the environment, as for
    ``study simulate``."""
    from analysis.load import read_database
    from analysis.power import power
    from analysis.report import select
    from study_server import create_app, upgrade_database

    from .run import simulate

    per_set = []
    with tempfile.TemporaryDirectory(prefix="scenesuggest-power-") as tmp:
        for k, human in enumerate(humans):
            url = f"sqlite:///{Path(tmp) / f'pilot-{k}.sqlite3'}"
            app = create_app({"SQLALCHEMY_DATABASE_URI": url, "INSTANCE_PATH": str(Path(tmp) / f"instance-{k}")})
            upgrade_database(app)
            summary = simulate(pilot, seed + k, study=study_id, app=app, human=human,
                               progress=lambda label, k=k: progress(f"parameter set {k + 1}/{len(humans)}: {label}"))
            if summary["failures"]:
                raise RuntimeError(f"simulated participants could not finish: {summary['failures'][0]}")
            trials, picks, _, conditions, _ = select(read_database(url, study_id))
            result = {}
            for name, (measure, compared) in HYPOTHESES.items():
                table = power(trials, picks, [c for c in conditions if c in compared], sizes, studies, seed, alpha,
                              measures=[measure],
                              progress=lambda label, k=k, name=name: progress(f"set {k + 1}: {name}: {label}"))
                result[name] = {int(n): v[measure] for n, v in table["power"].items()}
            per_set.append(result)
    out = {"alpha": alpha, "target_power": TARGET_POWER, "studies": studies, "pilot_participants": pilot,
           "seed": seed, "parameter_sets": len(humans), "hypotheses": {}}
    for name in HYPOTHESES:
        powers = [r[name] for r in per_set]
        counts = [needed(p) for p in powers]
        reached = [c for c in counts if c is not None]
        out["hypotheses"][name] = {
            "power": {str(n): {"best": powers[0][n], "low": float(np.min([p[n] for p in powers])),
                               "high": float(np.max([p[n] for p in powers]))} for n in sizes},
            "needed": {"best": counts[0], "low": min(reached) if reached else None,
                       "high": None if len(reached) < len(counts) else max(reached)},
        }
    return out
