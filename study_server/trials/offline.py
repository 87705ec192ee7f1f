"""A study's answers to a participant's page, given in process without a participant: the scene, the fixed model
list, the search results and the context suggestions exactly as the API gives them, with no list recorded and no
event stored. For
rehearsing a study's trials many times over (the simulation's calibration), where a real session per rehearsal
would only add database writes."""

from __future__ import annotations

from flask import Flask

from ..studies.served import StudyRuntime, runtime
from ..studies.study_file import Study
from . import lists


class OfflineAnswers:
    """The API's answers for study ``study_id`` of ``app`` (JSON-ready dicts, URLs below the app's root)."""

    def __init__(self, app: Flask, study_id: str):
        self.app = app
        with app.test_request_context():
            self.rt: StudyRuntime = runtime(study_id)

    @property
    def study(self) -> Study:
        return self.rt.study

    def scene(self, scene_id: str, which: str = "target") -> dict:
        """``GET /api/scenes/<scene_id>?which=``: the scene's target or start arrangement."""
        return self.rt.scene(scene_id, which)

    def models(self) -> dict:
        """``GET /api/models``: the fixed list, in its order."""
        with self.app.test_request_context():
            return {"models": [self.rt.describe(m) for m in self.rt.fixed_list]}

    def search(self, text: str, limit: int = 60) -> dict:
        """``GET /api/search?q=``: the hits for ``text``, best first (``list_id`` null: nothing is recorded)."""
        with self.app.test_request_context():
            hits = self.rt.search_index.search(text, limit)
            return {"list_id": None, "query": text,
                    "hits": [dict(self.rt.describe(self.rt.library[h.model_id]), rank=i + 1)
                             for i, h in enumerate(hits)]}

    def suggest(self, condition: str, scene_id: str, trial: int, data: dict) -> dict:
        """``POST /api/suggest`` in ``condition`` for a click in trial ``trial`` on scene ``scene_id`` (``data`` as
        the editor posts it: ``scene``, ``parent``, ``point``, ``normal``; metres, world frame). The list is not
        stored: its ``list_id`` is a fresh id that names nothing."""
        with self.app.test_request_context():
            return lists.suggest(self.rt, None, condition, scene_id, trial, data)
