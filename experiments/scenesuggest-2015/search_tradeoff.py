"""Why the calibrated bots search less than the paper's participants in `none`: keyword queries, total time, MRR
and rank shares of the replication's `none` trials as the share of objects searched for first (``search_first``),
the list patience (items scanned before giving up on the list), the share of first searches mistyped
(``unknown_words``) and of searches with one tag word (``tag_words``) move away from the calibrated values,
everything else as calibrated. One JSON line per setting, with the loss against the paper's `none` cells (without
the prior).

Run after ``make replication`` (it needs the prepared study and ``calibration/none.json``)::

    DATABASE_URL=sqlite:////tmp/tradeoff.sqlite3 SCENESUGGEST_INSTANCE=var/experiments/scenesuggest-2015/run/instance \\
    SCENESUGGEST_STUDIES=$PWD/experiments/scenesuggest-2015/study.toml \\
    .venv/bin/python experiments/scenesuggest-2015/search_tradeoff.py

About a minute: each setting rehearses the `none` trials of 40 bots (seed 0), as the calibration does.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from simulation.calibrate import Rehearsal, loss, read  # noqa: E402
from simulation.paper_tables import cells  # noqa: E402
from study_server import create_app, upgrade_database  # noqa: E402

#: Settings: parameter → value; the rest as calibrated.
SETTINGS = [{}, {"search_first": 0.5}, {"search_first": 0.95}, {"list_patience": 40.0},
            {"search_first": 0.95, "list_patience": 15.0}, {"unknown_words": 0.5}, {"unknown_words": 0.9},
            {"tag_words": 0.9}, {"unknown_words": 0.9, "tag_words": 0.9}]


def main() -> int:
    app = create_app()
    upgrade_database(app)
    rehearsal = Rehearsal(app, "scenesuggest-2015", participants=40, seed=0)
    calibrated = read(HERE / "calibration" / "none.json", rehearsal.study, ("none",))
    for changes in SETTINGS:
        human = calibrated.with_values(changes)
        measured = rehearsal.measure(human)
        print(json.dumps({**{k: round(getattr(human, k), 3) for k in ("search_first", "list_patience",
                                                                        "unknown_words", "tag_words")},
                          "loss": round(loss(measured, cells(("none",))), 2),
                          **{k: round(v, 3) for k, v in measured["none"].items()}}),
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
