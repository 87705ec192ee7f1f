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

from scenesuggest import scene_json
from scenesuggest.errors import SceneSuggestError
from scenesuggest.scene import Scene

from .errors import RequestError

MAX_IMAGE_BYTES = 8 * 1024 * 1024
MAX_IMAGE_PX = 4096
PNG_PREFIX = "data:image/png;base64,"


def image_path(target: Path) -> Path:
    return target.with_suffix(".png")


def posted_scene(doc: dict) -> Scene:
    """A scene the editor posted (native JSON), parsed; a bad one is a 400 naming the field (``scene.…``)."""
    try:
        return scene_json.from_dict(doc, file="scene")
    except SceneSuggestError as e:
        raise RequestError(400, e.message, f"scene.{e.field}" if e.field else "scene") from None


def live_scene(doc, scene_type: str) -> Scene:
    """The participant's scene as the editor holds it (``{"objects": [...]}``), of the trial's scene type."""
    if not isinstance(doc, dict) or not isinstance(doc.get("objects"), list):
        raise RequestError(400, "expected {\"objects\": [...]} in the native scene format", "scene")
    return posted_scene({"format": scene_json.FORMAT, "version": scene_json.VERSION, "id": "live",
                         "scene_type": scene_type, "source": "editor", "objects": doc["objects"]})


def checked_scene(doc, scene_id: str, library: dict) -> Scene:
    """A posted target scene (native JSON) as ``scene_id``, after checking it parses, has a room and objects,
    and uses only models of the study's library."""
    if not isinstance(doc, dict):
        raise RequestError(400, "expected a scene object (the native scene JSON)", "scene")
    doc = {**doc, "id": scene_id}
    scene = posted_scene(doc)
    objects = [o for o in scene if o.parent is not None]
    if not scene.roots():
        raise RequestError(400, "the scene has no room (an object without a parent)", "scene.objects")
    if not objects:
        raise RequestError(400, "a target scene needs at least one object besides the room", "scene.objects")
    for i, o in enumerate(doc.get("objects", [])):
        if o.get("parent") is not None and o.get("model_id") not in library:
            raise RequestError(400, f"model {o.get('model_id')!r} is not in the study's model library",
                                 f"scene.objects[{i}].model_id")
    return scene


def checked_png(data_url) -> tuple[bytes, tuple[int, int]]:
    """The bytes and size of a posted PNG data URL."""
    from PIL import Image, UnidentifiedImageError

    if not isinstance(data_url, str) or not data_url.startswith(PNG_PREFIX):
        raise RequestError(400, f"expected a PNG data URL ({PNG_PREFIX}…)", "png")
    if len(data_url) > MAX_IMAGE_BYTES * 4 // 3 + len(PNG_PREFIX) + 4:
        raise RequestError(413, f"the image is larger than {MAX_IMAGE_BYTES // 2**20} MB", "png")
    try:
        data = base64.b64decode(data_url[len(PNG_PREFIX):], validate=True)
        with Image.open(io.BytesIO(data)) as image:
            if image.format != "PNG":
                raise RequestError(400, "not a PNG image", "png")
            size = image.size
            image.verify()
    except (binascii.Error, ValueError):
        raise RequestError(400, "the image is not valid base64", "png") from None
    except (UnidentifiedImageError, OSError, SyntaxError):
        raise RequestError(400, "not a readable PNG image", "png") from None
    if max(size) > MAX_IMAGE_PX:
        raise RequestError(400, f"the image is larger than {MAX_IMAGE_PX} px on a side", "png")
    return data, size
