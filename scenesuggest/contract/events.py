"""The interaction-event vocabulary: every event type the editor logs and the fields of its payload.

One definition serves three readers: the study server validates each incoming event against it, the
browser client receives it as JSON Schema (:mod:`scenesuggest.contract.event_schema`), and the analysis reads events by
these names. An event is ``{"seq": int ≥ 0, "t": ms since the epoch (client clock), "type": name,
"trial": trial index or null, "payload": {...}}``; ``seq`` numbers a participant's events from 0 without
gaps, which is what makes ingestion idempotent and loss detectable.

The vocabulary has versions; a batch says which one its page speaks (``vocabulary``; 1 when absent, as pages
of the first version sent). Version 2 adds to every scene-changing event (:data:`SCENE_CHANGES`) the state after
the event of every object it changed (``objects``, :data:`OBJECT_STATE`), so that a trial can be rebuilt from
its events alone (:mod:`scenesuggest.contract.replay`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..scenes.frames import FACES

#: Largest accepted string, list and batch sizes (a participant's events are small).
MAX_TEXT = 2000
MAX_LIST = 500
#: Strings in one list an event carries: a list shown may be a study's whole library in its fixed order (the
#: Stanford database has about 1,580 models with meshes; a model id is about 40 characters, so a list this long
#: is about 200 kB, within a batch's body limit).
MAX_STRINGS = 5000
MAX_BATCH = 500
#: Events a client sends per request (the browser's outbox, whose pages get it from the server, and the simulated
#: participants): well within MAX_BATCH, so that a batch cut short by size still fits.
SEND_BATCH = 200
#: Largest seq (the column is a 32-bit integer on PostgreSQL).
MAX_SEQ = 2**31 - 1
#: Largest string in an object state (ids, model ids, categories, surface types are tens of characters): every
#: state is kept, and the admin's replay carries each one, so its size bounds theirs.
MAX_STATE_TEXT = 200
SOURCES = ("context", "search", "fixed")
#: The vocabulary's versions: 2 added ``objects`` (the resulting object states) to the scene-changing events.
VERSION = 2
VERSIONS = (1, 2)
#: Events that change the scene; from version 2 each carries ``objects``.
SCENE_CHANGES = ("insert", "replace", "move_end", "rotate_end", "delete", "undo", "redo")
#: One object's state after an event: the object as a scene file lists it (:mod:`scenesuggest.scenes.scene_json`:
#: metres, world frame, the 4×4 transform column-major), or ``{"id": …, "removed": true}`` when the event took it
#: away. Key → (kind, nullable).
OBJECT_STATE = {"id": ("str", False), "model_id": ("str", False), "category": ("str", False),
                "size": ("size", False), "transform": ("matrix", False), "parent": ("str", True),
                "surface_type": ("str", True), "attachment_face": ("face", True), "contact_point": ("vec3", True),
                "contact_normal": ("vec3", True)}


@dataclass(frozen=True)
class Field:
    kind: str  # str | int | num | bool | vec3 | strs | enum
    required: bool = True
    nullable: bool = False
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    description: str = ""


def _f(kind, description="", **kw) -> Field:
    return Field(kind, description=description, **kw)


OBJECT = _f("str", "id of the object in the editor's scene")
VOCABULARY: dict[str, dict[str, Field]] = {
    "trial_start": {"scene": _f("str", "target scene id"), "condition": _f("enum", choices=("none", "basic", "full"))},
    "trial_done": {"objects": _f("int", "objects in the scene when done", minimum=0)},
    "instructions": {"page": _f("int", "instruction page shown", minimum=0)},
    "briefing": {"condition": _f("enum", "the condition whose instructions were shown before the trial",
                                 choices=("none", "basic", "full")),
                 "seconds": _f("num", "how long the page of the condition's instructions was open before the trial "
                                      "began (server clock; not trial time)", minimum=0)},
    "list_shown": {"source": _f("enum", "where the list came from", choices=SOURCES),
                   "items": _f("strs", "categories or model ids, best first (rank = position + 1)"),
                   "list_id": _f("str", "server id of the list, when the server made it", required=False,
                                 nullable=True)},
    "search": {"text": _f("str", "the search box's text")},
    "context_query": {"parent": OBJECT, "point": _f("vec3", "clicked point, metres, world frame"),
                      "normal": _f("vec3", "surface normal at the point"),
                      "list_id": _f("str", "server id of the suggestion list", required=False, nullable=True)},
    "insert": {"object": OBJECT, "model": _f("str", "model id"), "category": _f("str"),
               "rank": _f("int", "1-based rank in the list it was chosen from", nullable=True, minimum=1),
               "source": _f("enum", choices=SOURCES),
               "list_id": _f("str", required=False, nullable=True)},
    "replace": {"object": OBJECT, "replaces": _f("str", "id of the object it replaced"), "model": _f("str"),
                "category": _f("str"), "rank": _f("int", nullable=True, minimum=1),
                "source": _f("enum", choices=SOURCES),
                "list_id": _f("str", required=False, nullable=True)},
    "select": {"object": _f("str", "selected object, or null when deselected", nullable=True)},
    "move_start": {"object": OBJECT},
    "move_end": {"object": OBJECT, "distance": _f("num", "metres travelled", minimum=0),
                 "parent": _f("str", "support parent after the move", nullable=True, required=False)},
    "rotate_start": {"object": OBJECT},
    "rotate_end": {"object": OBJECT, "angle": _f("num", "degrees turned (signed)")},
    "delete": {"object": OBJECT},
    "undo": {"action": _f("str", "the undone action's event type")},
    "redo": {"action": _f("str", "the redone action's event type")},
    "camera": {"action": _f("enum", choices=("orbit", "zoom", "pan", "reset")),
               "distance": _f("num", "camera distance after the action, metres", required=False, minimum=0)},
    "focus": {"state": _f("enum", choices=("focus", "blur"))},
    "visibility": {"state": _f("enum", choices=("visible", "hidden"))},
    "resize": {"width": _f("int", minimum=0), "height": _f("int", minimum=0)},
    "pointer": {"kind": _f("enum", choices=("mouse", "touch", "pen"))},
    "wheel": {"dx": _f("num"), "dy": _f("num"), "mode": _f("int", minimum=0)},
    "resume": {"reason": _f("str", "why the page (re)started: reload, back, second tab, reconnect")},
    "client_error": {"message": _f("str")},
}


#: Version 2's ``objects`` field (see :data:`OBJECT_STATE`).
STATES = _f("states", "the state after the event of every object it changed, as a scene file lists objects "
                      "(id, model_id, category, size, transform: 16 numbers column-major, world frame, metres, "
                      "parent, surface_type, attachment_face, contact_point, contact_normal), or {id, removed: true} "
                      "for an object it took away: a delete takes the object's children with it, an undo of an "
                      "insert takes the object away, an undo of a move restores the pose before it")


def fields_of(kind: str, version: int = VERSION) -> dict[str, Field]:
    """The payload fields of an event type in a version of the vocabulary."""
    fields = VOCABULARY[kind]
    return {**fields, "objects": STATES} if version >= 2 and kind in SCENE_CHANGES else fields


_FIELDS = {(kind, version): fields_of(kind, version) for kind in VOCABULARY for version in VERSIONS}


class EventError(ValueError):
    """A malformed event; ``field`` is a path such as ``events[3].payload.rank``."""

    def __init__(self, message: str, field: str):
        super().__init__(message)
        self.message = message
        self.field = field


def text_problem(value: str) -> str | None:
    """Why a string cannot be stored as text (a lone surrogate is not Unicode; PostgreSQL refuses NUL), or None."""
    if "\x00" in value:
        return "must not contain NUL characters"
    if not value.isascii():
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            return "must be valid Unicode (it contains a lone surrogate)"
    return None


# Validation runs on every event a participant sends, so it is written for speed: checks return what is wrong
# (or None), and the field's path is only spelled out for an event that is refused.
class _Bad(Exception):
    """What is wrong with a value, and where below the field being checked (``[3].transform``)."""

    def __init__(self, message: str, below: str = ""):
        self.message, self.below = message, below


_NUMBER_TYPES = frozenset((int, float))
_STR = frozenset((str,))
_LENGTHS = {"size": 3, "vec3": 3, "matrix": 16}
_NUMBERS_MESSAGE = {"size": "expected three numbers ≥ 0 (metres)", "vec3": "expected three finite numbers",
                    "matrix": "expected 16 finite numbers (column-major)"}


def _text(value, limit: int = MAX_TEXT) -> None:
    if not isinstance(value, str) or len(value) > limit:
        raise _Bad(f"expected a string of at most {limit} characters")
    problem = text_problem(value)
    if problem:
        raise _Bad(problem)


def _plain_texts(values: list) -> bool:
    """Every item is an ASCII string without NUL of at most MAX_TEXT characters (checked in C, all at once)."""
    if not values:
        return True
    if type(values[0]) is not str or not _STR.issuperset(map(type, values)):
        return False
    joined = "".join(values)
    return joined.isascii() and "\x00" not in joined and max(map(len, values)) <= MAX_TEXT


def _number(v) -> bool:
    """A finite number (booleans are not numbers; nor is an integer too large for a float)."""
    try:
        return type(v) in _NUMBER_TYPES and math.isfinite(v)
    except OverflowError:
        return False


def _numbers(v, n: int) -> bool:
    """A list of ``n`` finite numbers (as :func:`_number`)."""
    try:
        return (type(v) is list and len(v) == n and _NUMBER_TYPES.issuperset(map(type, v))
                and all(map(math.isfinite, v)))
    except OverflowError:
        return False


_STATE_KEYS = frozenset(OBJECT_STATE)
_STATE_TEXTS = tuple((k, nullable) for k, (kind, nullable) in OBJECT_STATE.items() if kind == "str")
_STATE_NUMBERS = tuple((k, nullable, kind) for k, (kind, nullable) in OBJECT_STATE.items()
                       if kind in _LENGTHS)


def _check_state(state) -> None:
    if type(state) is not dict:
        raise _Bad("expected an object")
    if "removed" in state:
        if state["removed"] is not True or len(state) != 2 or "id" not in state:
            raise _Bad('a removed object is {"id": …, "removed": true}')
        try:
            _text(state["id"], MAX_STATE_TEXT)
        except _Bad as e:
            raise _Bad(e.message, ".id") from None
        return
    if state.keys() != _STATE_KEYS:
        unknown = [k for k in state if k not in _STATE_KEYS]
        if unknown:
            raise _Bad("unknown field", f".{unknown[0]}")
        raise _Bad("missing", f".{next(k for k in OBJECT_STATE if k not in state)}")
    for key, nullable in _STATE_TEXTS:
        v = state[key]
        if v is None and nullable:
            continue
        try:
            _text(v, MAX_STATE_TEXT)
        except _Bad as e:
            raise _Bad(e.message, f".{key}") from None
    face = state["attachment_face"]
    if face is not None and face not in FACES:
        raise _Bad(f"must be one of {', '.join(FACES)}", ".attachment_face")
    for key, nullable, kind in _STATE_NUMBERS:
        v = state[key]
        if v is None and nullable:
            continue
        if not _numbers(v, _LENGTHS[kind]) or (kind == "size" and min(v) < 0):
            raise _Bad(_NUMBERS_MESSAGE[kind], f".{key}")


def _check_states(value) -> None:
    if type(value) is not list or len(value) > MAX_LIST:
        raise _Bad(f"expected a list of at most {MAX_LIST} object states")
    for i, state in enumerate(value):
        try:
            _check_state(state)
        except _Bad as e:
            raise _Bad(e.message, f"[{i}]{e.below}") from None
    if len({state["id"] for state in value}) < len(value):  # one state per object: which would count?
        seen = set()
        i = next(i for i, state in enumerate(value) if state["id"] in seen or seen.add(state["id"]))
        raise _Bad("a second state of the same object", f"[{i}].id")


def _check_field(spec: Field, value) -> None:
    if value is None:
        if spec.nullable:
            return
        raise _Bad("must not be null")
    k = spec.kind
    if k == "str" or k == "enum":
        _text(value)
        if k == "enum" and value not in spec.choices:
            raise _Bad(f"must be one of {', '.join(spec.choices)}")
    elif k == "int":
        if type(value) is not int or not -MAX_SEQ <= value <= MAX_SEQ:
            raise _Bad(f"expected an integer of at most {MAX_SEQ} in size")
    elif k == "num":
        if not _number(value):
            raise _Bad("expected a finite number")
    elif k == "bool":
        if not isinstance(value, bool):
            raise _Bad("expected true or false")
    elif k == "vec3":
        if not _numbers(value, 3):
            raise _Bad("expected three finite numbers")
    elif k == "states":
        _check_states(value)
    elif k == "strs":
        if type(value) is not list or len(value) > MAX_STRINGS:
            raise _Bad(f"expected a list of at most {MAX_STRINGS} strings")
        if not _plain_texts(value):  # only then look at each string, to say which one is wrong
            for i, v in enumerate(value):
                try:
                    _text(v)
                except _Bad as e:
                    raise _Bad(e.message, f"[{i}]") from None
    if spec.minimum is not None and (k == "int" or k == "num") and value < spec.minimum:
        raise _Bad(f"must be at least {spec.minimum:g}")


#: The keys of an event, as the page sends it and as every reader takes it back (:func:`as_event`).
EVENT_KEYS = ("seq", "t", "type", "trial", "payload")
_KEYS = frozenset(EVENT_KEYS)


def as_event(seq, t, kind: str, trial, payload) -> dict:
    """A stored event (a database row's or an export row's fields) in the shape the page sent it and every reader
    of events takes it: ``seq`` and ``trial`` integers (a missing trial — None, or NaN as pandas reads an empty
    cell — is None), ``t`` the client clock in ms since the epoch, ``payload`` as stored."""
    return {"seq": int(seq), "t": t, "type": kind, "trial": None if trial is None or trial != trial else int(trial),
            "payload": payload}


def validate_event(event, path: str = "event", version: int = VERSION) -> dict:
    """Check one event against ``version`` of the vocabulary; returns it normalised (``trial`` defaults to
    null)."""
    if not isinstance(event, dict):
        raise EventError("expected an object", path)
    if not _KEYS.issuperset(event):
        raise EventError("unknown field", f"{path}.{sorted(set(event) - _KEYS)[0]}")
    seq = event.get("seq")
    if type(seq) is not int or not 0 <= seq <= MAX_SEQ:
        raise EventError(f"expected an integer from 0 to {MAX_SEQ}", f"{path}.seq")
    t = event.get("t")
    if not _number(t):
        raise EventError("expected a finite number (ms since the epoch)", f"{path}.t")
    kind = event.get("type")
    if kind not in VOCABULARY:
        raise EventError(f"unknown event type {kind!r}" if isinstance(kind, str) else "expected a string",
                         f"{path}.type")
    trial = event.get("trial")
    if trial is not None and (type(trial) is not int or not -1 <= trial < 1000):
        raise EventError("expected a trial index or null", f"{path}.trial")
    payload = event.get("payload", {})
    if not isinstance(payload, dict):
        raise EventError("expected an object", f"{path}.payload")
    fields = _FIELDS[kind, version]
    for name in payload:
        if name not in fields:
            raise EventError("unknown field", f"{path}.payload.{name}")
    for name, spec in fields.items():
        if name in payload:
            try:
                _check_field(spec, payload[name])
            except _Bad as e:
                raise EventError(e.message, f"{path}.payload.{name}{e.below}") from None
        elif spec.required:
            raise EventError("missing", f"{path}.payload.{name}")
    return {"seq": seq, "t": float(t), "type": kind, "trial": trial, "payload": payload}


def check_version(version) -> int:
    """A batch's ``vocabulary`` (absent: 1, what pages of the first version sent)."""
    if version is None:
        return 1
    if type(version) is not int or version not in VERSIONS:  # 2.0 is not a version
        raise EventError(f"must be one of {', '.join(map(str, VERSIONS))}", "vocabulary")
    return version


def validate_batch(events, version: int = VERSION) -> list[dict]:
    """Validate a whole batch before anything is stored (all or nothing)."""
    if not isinstance(events, list):
        raise EventError("expected a list of events", "events")
    if len(events) > MAX_BATCH:
        raise EventError(f"at most {MAX_BATCH} events per batch", "events")
    out = []
    for i, e in enumerate(events):
        try:
            out.append(validate_event(e, "", version))
        except EventError as error:  # the path of the event in the batch, spelled out only now
            raise EventError(error.message, f"events[{i}]{error.field}") from None
    seqs = [e["seq"] for e in out]
    if len(set(seqs)) != len(seqs):
        raise EventError("the same seq appears twice in one batch", "events")
    return out
