"""Run simulated participants (:mod:`.participant`) through a study, in process or against a running server,
and summarise what they did (``scenesuggest study simulate``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .human import Human
from .participant import Behaviours, Bot
from .transport import FlaskTransport, FlowError, HttpTransport

#: The entry-link parameter that names the participant, per platform.
PLATFORM_IDS = ("pid", "PROLIFIC_PID", "workerId")


def _platform_id(query: dict | None) -> str | None:
    return next((query[k] for k in PLATFORM_IDS if k in query), None) if query else None


#: How long a bot keeps sending a request that finds no server (refused, reset, 502/503), as a browser's page does.
RETRY_S = 60.0


def simulate(participants: int, seed: int = 0, *, study: str, url: str | None = None, app=None,
             behaviours: Behaviours | None = None, human: Human | None = None,
             entry: Callable[[int], dict] | None = None,
             progress: Callable[[str], None] = lambda label: None) -> dict:
    """Run ``participants`` bots one after another through ``study`` (bot i draws from the generator seeded
    ``[seed, i]``), behaving as ``human`` (default :class:`~.human.Human`; a calibration's fit:
    :func:`.calibrate.read`); the scenes' difficulty is drawn from ``seed``.

    With ``url`` they talk HTTP to that server; otherwise to ``app`` (a Flask app) through its test client.
    ``entry(i)`` gives bot i's entry-link parameters (``scenesuggest study simulate``: a pilot's, signed and shaped
    for the study's platform); default ``pid=sim-SEED-i``.
    Returns the counts of completed participants, trials, events sent and objects the bots could not find, and
    the mean simulated seconds per condition.
    """
    if url is None and app is None:
        raise ValueError("give a server URL or an app")
    results, failures, retries, symmetry = [], [], 0, {}
    for i in range(participants):
        transport = HttpTransport(url, retry_for=RETRY_S) if url else FlaskTransport(app.test_client())
        query = entry(i) if entry is not None else None
        bot = Bot(transport, study, _platform_id(query) or f"sim-{seed}-{i}", np.random.default_rng([seed, i]),
                  behaviours=behaviours, symmetry=symmetry, human=human, scene_seed=seed, entry=query)
        try:
            results.append(bot.run())
        except FlowError as e:
            failures.append({"participant": bot.pid, "error": str(e)})
        retries += getattr(bot.http, "retries", 0)
        progress(f"participant {i + 1}/{participants}")
    seconds: dict[str, list[float]] = {}
    for r in results:
        for c, values in r.condition_seconds.items():
            seconds.setdefault(c, []).extend(values)
    return {"study": study, "participants": participants, "completed": sum(r.code is not None for r in results),
            "dropped_out": sum(r.dropped_out for r in results), "reloads": sum(r.reloads for r in results),
            "requests_repeated": retries,
            "trials": sum(r.trials for r in results), "events": sum(r.events for r in results),
            "missing_objects": sum(r.missing_objects for r in results), "failures": failures,
            "mean_seconds": {c: float(np.mean(v)) for c, v in seconds.items()}}
