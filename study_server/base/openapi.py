"""The OpenAPI 3.1 document of the JSON API (served at /api/openapi.json, used by the API tests and fuzzers)."""

from __future__ import annotations

from scenesuggest.contract.event_schema import json_schema
from scenesuggest.contract.events import MAX_BATCH, MAX_SEQ, VERSIONS
from scenesuggest.engines.wire import ANSWER_SCHEMA, QUERY_SCHEMA

ERROR = {"type": "object", "required": ["error"],
         "properties": {"error": {"type": "string"}, "field": {"type": ["string", "null"]}}}
VEC3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
SCENE = {"type": "object", "required": ["objects"], "description": "The editor's scene: objects in the native "
         "scene format (id, model_id, category, size, transform, parent, …)",
         "properties": {"objects": {"type": "array", "items": {"type": "object"}}}}
MODEL = {"type": "object", "properties": {"id": {"type": "string"}, "name": {"type": "string"},
                                          "category": {"type": "string"},
                                          "category_path": {"type": "array", "items": {"type": "string"},
                                                            "description": "the category's path in the "
                                                                           "taxonomy"},
                                          "tags": {"type": "array", "items": {"type": "string"},
                                                   "description": "the model's search words"},
                                          "asset": {"type": "string"},
                                          "thumbnail": {"type": "string"}, "size": VEC3}}


def _errors(*codes: int) -> dict:
    return {str(c): {"description": "error", "content": {"application/json": {"schema": ERROR}}} for c in codes}


def _ok(schema: dict, description: str = "ok") -> dict:
    return {"200": {"description": description, "content": {"application/json": {"schema": schema}}}}


def _body(schema: dict) -> dict:
    return {"required": True, "content": {"application/json": {"schema": schema}}}


def _components() -> dict:
    """The security scheme (the participant's bearer token) and the named schemas."""
    return {"securitySchemes": {"session": {"type": "http", "scheme": "bearer",
                                            "description": "the participant's session token"}},
            "schemas": {"Event": json_schema(), "Error": ERROR,
                        # what the server POSTs to a condition's http engine, and what it must answer
                        # (scenesuggest.engines.http; not endpoints of this API)
                        "EngineQuery": QUERY_SCHEMA, "EngineAnswer": ANSWER_SCHEMA}}


def _session_paths(auth: list) -> dict:
    """The session's state and its heartbeat."""
    return {
        "/api/session": {"get": {"summary": "Session state", "security": auth,
                                 "responses": {**_ok({"type": "object"}), **_errors(401)}}},
        "/api/heartbeat": {"post": {"summary": "Keep the session fresh", "security": auth,
                                    "responses": {**_ok({"type": "object"}), **_errors(401)}}},
    }


def _events_paths(auth: list) -> dict:
    """The batches of events a page logs."""
    return {
        "/api/events": {"post": {
            "summary": "Store a batch of events (idempotent by seq); answers the highest contiguous seq stored. "
                       "409: seqs already hold other events (``conflicts``: batch positions, ``next_seq``: send "
                       "them again from there; nothing stored); 410: the session has ended; 429: over a "
                       "quota (wait ``Retry-After``)",
            "security": auth,
            "requestBody": _body({"type": "object", "required": ["page_id", "events"], "properties": {
                "page_id": {"type": "string", "pattern": "^[A-Za-z0-9_.-]{1,64}$"},
                "vocabulary": {"type": "integer", "enum": list(VERSIONS), "default": 1,
                               "description": "the event vocabulary's version the page speaks (2: the "
                                              "scene-changing events carry the resulting object states)"},
                "events": {"type": "array", "maxItems": MAX_BATCH, "items": {"$ref": "#/components/schemas/Event"}},
            }}),
            "responses": {**_ok({"type": "object", "required": ["acked_seq"],
                                 "properties": {"acked_seq": {"type": "integer"}}}),
                          **_errors(400, 401, 409, 410, 413, 422, 429)}}},
    }


def _model_paths(auth: list) -> dict:
    """What the editor asks for models by: suggestions for a click, keyword search, the whole list."""
    return {
        "/api/suggest": {"post": {
            "summary": "Contextual suggestions for a click in the current trial (not in the 'none' condition)",
            "security": auth,
            "requestBody": _body({"type": "object", "required": ["trial", "parent", "point", "normal", "scene"],
                                  "properties": {"trial": {"type": "integer"}, "parent": {"type": "string"},
                                                 "point": VEC3, "normal": VEC3, "scene": SCENE}}),
            "responses": {**_ok({"type": "object", "properties": {
                "list_id": {"type": "string"}, "surface_type": {"type": "string"},
                "engine": {"type": "string", "description": "the engine that answered: the condition's, or its "
                                                            "fallback's when an http engine could not"},
                "suggestions": {"type": "array", "items": {"type": "object"}}}}),
                **_errors(400, 401, 403, 409)}}},
        "/api/search": {"get": {
            "summary": "Keyword search over the study's models", "security": auth,
            "parameters": [{"name": "q", "in": "query", "required": False,
                            "schema": {"type": "string", "maxLength": 200}},
                           {"name": "limit", "in": "query", "required": False,
                            "schema": {"type": "integer", "minimum": 1, "maximum": 200}}],
            "responses": {**_ok({"type": "object", "properties": {"hits": {"type": "array", "items": MODEL}}}),
                          **_errors(400, 401)}}},
        "/api/models": {"get": {"summary": "Every model of the study, in the fixed order", "security": auth,
                                "responses": {**_ok({"type": "object", "properties": {
                                    "models": {"type": "array", "items": MODEL}}}), **_errors(401)}}},
    }


def _trial_paths(auth: list) -> dict:
    """A trial's target and start scenes, and its end."""
    return {
        "/api/scenes/{scene_id}": {"get": {
            "summary": "A target or start scene of this session (native scene JSON); `progress`: the current "
                       "trial's scene as its stored events rebuild it, with `changes` and `last_change_seq`",
            "security": auth,
            "parameters": [{"name": "scene_id", "in": "path", "required": True, "schema": {"type": "string"}},
                           {"name": "which", "in": "query", "required": False,
                            "schema": {"type": "string", "enum": ["target", "start", "progress"]}}],
            "responses": {**_ok({"type": "object"}), **_errors(400, 401, 404)}}},
        "/api/trial/done": {"post": {
            "summary": "Finish the current trial with its final scene", "security": auth,
            "requestBody": _body({"type": "object", "required": ["trial"], "properties": {
                "trial": {"type": "integer", "minimum": -1}, "scene": SCENE,
                "last_seq": {"type": "integer", "minimum": -1, "maximum": MAX_SEQ,
                             "description": "the seq of the last event the page logged (its trial_done): the "
                                            "server checks the trial's replay once it holds every event up "
                                            "to it"}}}),
            "responses": {**_ok({"type": "object"}), **_errors(400, 401, 409, 410, 422)}}},
    }


def _schema_paths() -> dict:
    """The documents that describe the API, served without a session."""
    return {
        "/api/events/schema.json": {"get": {"summary": "JSON Schema of one event",
                                            "responses": _ok({"type": "object"})}},
        "/api/openapi.json": {"get": {"summary": "This document", "responses": _ok({"type": "object"})}},
    }


def openapi_document() -> dict:
    """The OpenAPI 3.1 document, its paths in a fixed order (the session's, events, models, trials, schemas)."""
    auth = [{"session": []}]
    return {
        "openapi": "3.1.0",
        "info": {"title": "SceneSuggest Studio participant API", "version": "1"},
        "components": _components(),
        "paths": {**_session_paths(auth), **_events_paths(auth), **_model_paths(auth), **_trial_paths(auth),
                  **_schema_paths()},
    }
