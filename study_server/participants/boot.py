"""The boot data of the scene editor's page (``<script id="boot">``), the same for a participant's trial, an
admin's preview and the target editor: who is asking (token), which trial, where the API is, where to go next,
and the version of the event vocabulary the page logs in."""

from __future__ import annotations

import secrets

from flask import url_for

from scenesuggest.contract.events import SEND_BATCH
from scenesuggest.contract.events import VERSION as EVENT_VOCABULARY

from ..studies.study_file import Study


def api_base() -> str:
    """Where the JSON API is for this request (below the app's mount point): for the editor's boot data and the
    exit pages, which flush the outbox there."""
    return url_for("api.session_state").rsplit("/", 1)[0]


def trial_boot(study: Study, token: str, trial: dict, next_url: str, preview: bool = False) -> dict:
    """``trial``: index, kind, condition, scene, block, number and of (the trial's place among the trials)."""
    return {"study": study.id, "token": token, "preview": preview, "trial": trial, "page_id": secrets.token_hex(8),
            "api": api_base(), "next": next_url,
            "limits": {"trial_minutes": study.trial_minutes}, "vocabulary": EVENT_VOCABULARY, "batch": SEND_BATCH}
