"""How many participants a study needs, from the calibrated simulator (``scenesuggest study power``).

For each of the calibration's parameter sets (:func:`.calibrate.read_plausible`: the best fit first, then its refits
on the paper's cells drawn from their sampling distributions, or without draws the sets its cells fit almost as
well — the calibration's uncertainty), a pilot of simulated
participants takes the study in process on a database of its own; :func:`analysis.power.power` then resamples
that pilot into studies of each size and counts how often each hypothesis' likelihood-ratio test rejects. The
participants needed for a power are the smallest size that reaches it, per parameter set, so the answer comes
as the best fit's figure with the range over the plausible sets.

With another study file of the same study whose conditions other engines serve (``--against``), the same bots
take that one too, and the two runs are read as one study in which every participant builds the ``full`` scenes
with both engines: the power to tell the engines apart (ENGINE_HYPOTHESES), what an experimenter planning an
engine comparison asks first.
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
#: The engine comparison's hypotheses: name → (measure, condition whose two engines are compared).
ENGINE_HYPOTHESES = {
    "E1 total time (full: the study's engine vs the other)": ("total_time", "full"),
    "E2 MRR (full: the study's engine vs the other)": ("reciprocal_rank", "full"),
}
OTHER = "·other"  # the suffix of the other study's conditions in the paired runs
TARGET_POWER = 0.8


def needed(power_by_size: dict[int, float], target: float = TARGET_POWER) -> int | None:
    """The smallest size whose power reaches ``target`` (None: none of them does)."""
    return next((n for n in sorted(power_by_size) if power_by_size[n] >= target), None)


def _pilot(tmp: Path, name: str, study_id: str, human, participants: int, seed: int, study_file: Path | None,
           progress: Callable[[str], None]):
    """``participants`` bots (seed ``seed``) behaving as ``human`` through study ``study_id`` (of ``study_file``,
    default the environment's) on a database of their own; returns (trials, picks) as the report selects them."""
    from analysis.load import read_database
    from analysis.report import select
    from study_server import create_app, upgrade_database

    from .run import simulate

    url = f"sqlite:///{tmp / f'{name}.sqlite3'}"
    config = {"SQLALCHEMY_DATABASE_URI": url, "INSTANCE_PATH": str(tmp / f"instance-{name}")}
    app = create_app(config | ({"STUDY_FILES": [str(study_file)]} if study_file else {}))
    upgrade_database(app)
    summary = simulate(participants, seed, study=study_id, app=app, human=human, progress=progress)
    if summary["failures"]:
        raise RuntimeError(f"simulated participants could not finish: {summary['failures'][0]}")
    trials, picks, _, _, _ = select(read_database(url, study_id))
    return trials, picks


def _plans(trials) -> dict:
    """Each participant's trials as (position, scene, condition), in order."""
    ordered = trials.sort_values(["participant", "position"])
    return {p: list(zip(g["position"], g["scene"], g["condition"], strict=True))
            for p, g in ordered.groupby("participant")}


def paired(a: tuple, b: tuple) -> tuple:
    """Two runs of the same bots (trials and picks of each) as one study: ``b``'s conditions renamed with OTHER.
    Each bot must have the same participant id and the same trials (positions, scenes, conditions) in both (they
    arrive in the same order on fresh databases); anything else is an error."""
    import pandas as pd

    if _plans(a[0]) != _plans(b[0]):
        raise RuntimeError("the two runs' participants do not pair up (other ids, scenes or conditions)")
    other = [frame.assign(condition=frame["condition"].astype(str) + OTHER) for frame in b]
    return (pd.concat([a[0], other[0]], ignore_index=True), pd.concat([a[1], other[1]], ignore_index=True))


def study_power(study_id: str, humans: list, sizes: list[int], studies: int, pilot: int, seed: int = 0,
                alpha: float = 0.05, progress: Callable[[str], None] = lambda message: None,
                against: Path | None = None) -> dict:
    """Power of each of HYPOTHESES at each of ``sizes`` for every parameter set of ``humans`` (the best first),
    from a pilot of ``pilot`` simulated participants each; the studies configured by the environment, as for
    ``study simulate``. With ``against`` (a study file of the same study, other engines), the power of
    ENGINE_HYPOTHESES instead, from the same bots taking both."""
    from analysis.power import power

    hypotheses = ENGINE_HYPOTHESES if against else HYPOTHESES
    per_set = []
    with tempfile.TemporaryDirectory(prefix="scenesuggest-power-") as tmp:
        for k, human in enumerate(humans):
            said = lambda label, k=k: progress(f"parameter set {k + 1}/{len(humans)}: {label}")  # noqa: E731
            run = _pilot(Path(tmp), f"pilot-{k}", study_id, human, pilot, seed + k, None, said)
            trials, picks = run
            if against:
                trials, picks = paired(run, _pilot(Path(tmp), f"other-{k}", study_id, human, pilot, seed + k,
                                                   against, said))
            result = {}
            for name, (measure, compared) in hypotheses.items():
                conditions = ([compared, compared + OTHER] if against else
                              [c for c in compared if c in set(trials["condition"])])
                table = power(trials, picks, conditions, sizes, studies, seed, alpha, measures=[measure],
                              progress=lambda label, k=k, name=name: progress(f"set {k + 1}: {name}: {label}"))
                result[name] = {int(n): v[measure] for n, v in table["power"].items()}
            per_set.append(result)
    out = {"alpha": alpha, "target_power": TARGET_POWER, "studies": studies, "pilot_participants": pilot,
           "seed": seed, "parameter_sets": len(humans), "against": str(against) if against else None,
           "hypotheses": {}}
    for name in hypotheses:
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
