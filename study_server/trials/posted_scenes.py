"""Scenes the editor posts: the participant's live scene (for suggestions and at "done"), and saving a target
scene, and its image, from the admin's scene editor.

A target is written where the study file says it lives (``[[scenes]] target``), its image beside it with the
extension ``.png``. Both are checked in full before anything is written, and written atomically
(:mod:`scenesuggest.atomic`), so a bad request never leaves a half-written scene. Once participants have
started a study its targets are frozen: what they were shown must stay what the export describes.
"""

from __future__ import annotations

import base64
import binascii
import io
from pathlib import Path

from sqlalchemy import func, select

from scenesuggest.atomic import write_atomically
from scenesuggest.errors import SceneSuggestError
from scenesuggest.scenes import scene_json
from scenesuggest.scenes.scene import Scene

from ..base.config import part_of_the_package
from ..base.errors import StudyError
from ..base.extensions import db
from ..base.models import Participant
from ..studies.served import StudyRuntime

MAX_IMAGE_BYTES = 8 * 1024 * 1024
MAX_IMAGE_PX = 4096


class SceneRejected(StudyError):
    """A posted scene or image that cannot be used, and which field of it is wrong."""

    status = 400


class ImageTooLarge(SceneRejected):
    status = 413


class TargetsFrozen(StudyError):
    """The study's targets may not change: participants have started it, or its files are the package's."""


def started(study_id: str) -> int:
    """How many participants have consented (hold a schedule row): the study's targets are then frozen. Pilots
    (test runs and simulated participants) do not freeze them."""
    return db.session.scalar(select(func.count()).select_from(Participant)
                             .where(Participant.study_id == study_id, Participant.row >= 0,
                                    Participant.pilot.is_(False))) or 0


def may_author(rt: StudyRuntime) -> None:
    """Refuse (:class:`TargetsFrozen`) to change the targets of a study whose files ship with the installed package,
    or that participants have started."""
    if part_of_the_package(rt.study.path):
        raise TargetsFrozen("this study ships with the installed package, whose files are read-only: author on a "
                            "copy of the study", "scene_id")
    count = started(rt.study.id)
    if count:
        raise TargetsFrozen(f"{count} participant(s) have started this study: its target scenes are frozen (author "
                            "on a copy of the study)", "scene_id")


def save_target(rt: StudyRuntime, scene_id: str, doc) -> tuple[Path, int]:
    """Check the posted target of ``scene_id`` in full and write it where the study file says (atomically);
    returns the path and how many objects it has besides the room."""
    may_author(rt)
    scene = checked_scene(doc, scene_id, rt.library)
    target = rt.study.scenes[scene_id].target
    scene_json.save(scene, target)
    return target, len(scene) - 1


def save_image(rt: StudyRuntime, scene_id: str, data_url) -> tuple[Path, int, int]:
    """Check the posted PNG data URL and write it beside the target of ``scene_id``; returns the path, its width
    and height in pixels."""
    may_author(rt)
    data, (width, height) = checked_png(data_url)
    return write_atomically(image_path(rt.study.scenes[scene_id].target), data), width, height
PNG_PREFIX = "data:image/png;base64,"


def image_path(target: Path) -> Path:
    return target.with_suffix(".png")


def posted_scene(doc: dict) -> Scene:
    """A scene the editor posted (native JSON), parsed; a bad one is a 400 naming the field (``scene.…``)."""
    try:
        return scene_json.from_dict(doc, file="scene")
    except SceneSuggestError as e:
        raise SceneRejected(e.message, f"scene.{e.field}" if e.field else "scene") from None


def live_scene(doc, scene_type: str) -> Scene:
    """The participant's scene as the editor holds it (``{"objects": [...]}``), of the trial's scene type."""
    if not isinstance(doc, dict) or not isinstance(doc.get("objects"), list):
        raise SceneRejected("expected {\"objects\": [...]} in the native scene format", "scene")
    return posted_scene({"format": scene_json.FORMAT, "version": scene_json.VERSION, "id": "live",
                         "scene_type": scene_type, "source": "editor", "objects": doc["objects"]})


def checked_scene(doc, scene_id: str, library: dict) -> Scene:
    """A posted target scene (native JSON) as ``scene_id``, after checking it parses, has a room and objects,
    and uses only models of the study's library."""
    if not isinstance(doc, dict):
        raise SceneRejected("expected a scene object (the native scene JSON)", "scene")
    doc = {**doc, "id": scene_id}
    scene = posted_scene(doc)
    objects = [o for o in scene if o.parent is not None]
    if not scene.roots():
        raise SceneRejected("the scene has no room (an object without a parent)", "scene.objects")
    if not objects:
        raise SceneRejected("a target scene needs at least one object besides the room", "scene.objects")
    for i, o in enumerate(doc.get("objects", [])):
        if o.get("parent") is not None and o.get("model_id") not in library:
            raise SceneRejected(f"model {o.get('model_id')!r} is not in the study's model library",
                                 f"scene.objects[{i}].model_id")
    return scene


def checked_png(data_url) -> tuple[bytes, tuple[int, int]]:
    """The bytes and size of a posted PNG data URL."""
    from PIL import Image, UnidentifiedImageError

    if not isinstance(data_url, str) or not data_url.startswith(PNG_PREFIX):
        raise SceneRejected(f"expected a PNG data URL ({PNG_PREFIX}…)", "png")
    if len(data_url) > MAX_IMAGE_BYTES * 4 // 3 + len(PNG_PREFIX) + 4:
        raise ImageTooLarge(f"the image is larger than {MAX_IMAGE_BYTES // 2**20} MB", "png")
    try:
        data = base64.b64decode(data_url[len(PNG_PREFIX):], validate=True)
        with Image.open(io.BytesIO(data)) as image:
            if image.format != "PNG":
                raise SceneRejected("not a PNG image", "png")
            size = image.size
            image.verify()
    except (binascii.Error, ValueError):
        raise SceneRejected("the image is not valid base64", "png") from None
    except (UnidentifiedImageError, OSError, SyntaxError):
        raise SceneRejected("not a readable PNG image", "png") from None
    if max(size) > MAX_IMAGE_PX:
        raise SceneRejected(f"the image is larger than {MAX_IMAGE_PX} px on a side", "png")
    return data, size
