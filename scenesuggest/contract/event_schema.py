"""The event vocabulary (:mod:`scenesuggest.contract.events`) as JSON Schema 2020-12: what ``/api/events/schema.json``
serves, the OpenAPI document embeds and an export writes beside its events (one file per version they speak)."""

from __future__ import annotations

from .events import (
    FACES,
    MAX_LIST,
    MAX_SEQ,
    MAX_STATE_TEXT,
    MAX_STRINGS,
    MAX_TEXT,
    OBJECT_STATE,
    SCENE_CHANGES,
    VERSION,
    VOCABULARY,
    Field,
    fields_of,
)


def _state_schema() -> dict:
    number = {"type": "number"}
    kinds = {"str": {"type": "string", "maxLength": MAX_STATE_TEXT}, "face": {"type": "string", "enum": list(FACES)},
             "vec3": {"type": "array", "items": number, "minItems": 3, "maxItems": 3},
             "size": {"type": "array", "items": {"type": "number", "minimum": 0}, "minItems": 3,
                      "maxItems": 3},
             "matrix": {"type": "array", "items": number, "minItems": 16, "maxItems": 16}}
    present = {"type": "object", "additionalProperties": False, "required": list(OBJECT_STATE),
               "properties": {k: kinds[kind] if not nullable else {"anyOf": [kinds[kind], {"type": "null"}]}
                              for k, (kind, nullable) in OBJECT_STATE.items()}}
    removed = {"type": "object", "additionalProperties": False, "required": ["id", "removed"],
               "properties": {"id": kinds["str"], "removed": {"const": True}}}
    return {"type": "array", "maxItems": MAX_LIST, "items": {"oneOf": [present, removed]}}


def _field_schema(spec: Field) -> dict:
    if spec.kind == "states":
        return {**_state_schema(), "description": spec.description}
    kinds = {"str": {"type": "string", "maxLength": MAX_TEXT},
             "int": {"type": "integer", "minimum": -MAX_SEQ, "maximum": MAX_SEQ},
             "num": {"type": "number"}, "bool": {"type": "boolean"},
             "vec3": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
             "strs": {"type": "array", "items": {"type": "string", "maxLength": MAX_TEXT}, "maxItems": MAX_STRINGS},
             "enum": {"type": "string", "enum": list(spec.choices)}}
    schema = dict(kinds[spec.kind])
    if spec.minimum is not None:
        schema["minimum"] = spec.minimum
    if spec.description:
        schema["description"] = spec.description
    if spec.nullable:
        schema = {"anyOf": [schema, {"type": "null"}]}
    return schema


def payload_schema(kind: str, version: int = VERSION) -> dict:
    fields = fields_of(kind, version)
    return {"type": "object", "additionalProperties": False,
            "properties": {n: _field_schema(f) for n, f in fields.items()},
            "required": [n for n, f in fields.items() if f.required]}


def json_schema(version: int = VERSION) -> dict:
    """JSON Schema (2020-12) of one event of ``version`` of the vocabulary, with a branch per type."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": f"scenesuggest-event-v{version}",
        "title": "SceneSuggest Studio interaction event",
        "description": f"vocabulary version {version} (a batch of events says its version in 'vocabulary'; 1 when "
                       "absent). Version 2 adds 'objects', the resulting object states, to the scene-changing "
                       f"events ({', '.join(SCENE_CHANGES)}).",
        "x-vocabulary-version": version,
        "type": "object",
        "additionalProperties": False,
        "required": ["seq", "t", "type"],
        "properties": {
            "seq": {"type": "integer", "minimum": 0, "maximum": MAX_SEQ,
                    "description": "per-participant sequence number, from 0"},
            "t": {"type": "number", "description": "client time, ms since the epoch"},
            "type": {"type": "string", "enum": sorted(VOCABULARY)},
            "trial": {"anyOf": [{"type": "integer", "minimum": -1}, {"type": "null"}]},
            "payload": {"type": "object"},
        },
        "allOf": [{"if": {"properties": {"type": {"const": k}}},
                   "then": {"properties": {"payload": payload_schema(k, version)}}} for k in sorted(VOCABULARY)],
    }
