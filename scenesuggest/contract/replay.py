"""Rebuilding a trial from its events: the scene after each event, from the trial's start scene.

Pure and shared: the study server checks a finished trial with it, the admin's replay shows it, the analysis
measures how close a scene came to its target over time with it, and the tests compare it with the scenes the
editor submitted. It reads only the ``objects`` of the scene-changing events (vocabulary version 2,
:mod:`scenesuggest.contract.events`): each lists the state after the event of every object the event changed — the
object as a scene file lists it, or ``{"id": …, "removed": true}``.

An event is a mapping with ``type``, ``payload`` and, for :func:`scene_at`, ``t`` (client ms); events are given in
``seq`` order. A scene is a dict object id → object (scene-file form); objects are never modified in place, so
scenes of consecutive events share what did not change.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

from .events import SCENE_CHANGES

Scene = dict[str, dict]
#: Numbers of two scenes that differ by no more than this are the same (the client rounds states to 1e-7,
#: JSON keeps 17 significant digits; this absorbs float noise of a transform composed twice, metres).
TOLERANCE = 1e-6


class ReplayUnavailable(ValueError):
    """Events that do not carry their objects' states (vocabulary version 1): the trial cannot be rebuilt."""


def start_scene(objects: Iterable[dict]) -> Scene:
    """A scene from a list of objects (a start or target scene's ``objects``)."""
    return {o["id"]: o for o in objects}


def _states(event: Mapping) -> list[dict] | None:
    """The object states an event carries (None: it changes nothing)."""
    if event["type"] not in SCENE_CHANGES:
        return None
    states = event["payload"].get("objects")
    if states is None:
        raise ReplayUnavailable(f"a {event['type']} event without object states (vocabulary 1)")
    return states


def _put(scene: Scene, states: list[dict]) -> None:
    for state in states:
        if state.get("removed"):
            scene.pop(state["id"], None)
        else:
            scene[state["id"]] = state


def apply(scene: Scene, event: Mapping) -> Scene:
    """The scene after ``event``: the same scene for an event that changes nothing, else a new one."""
    states = _states(event)
    if not states:  # not a scene change, or one that changed no object
        return scene
    after = dict(scene)
    _put(after, states)
    return after


def replay(start: Iterable[dict] | Scene, events: Iterable[Mapping]) -> list[Scene]:
    """The scene after each of ``events`` (as many scenes as events), from ``start`` (objects or a scene)."""
    scene = dict(start) if isinstance(start, Mapping) else start_scene(start)
    out = []
    for event in events:
        scene = apply(scene, event)
        out.append(scene)
    return out


def final_scene(start: Iterable[dict] | Scene, events: Iterable[Mapping]) -> Scene:
    """The scene after the last event (the start scene when there is none): one scene changed in place, so time
    and memory grow with the events' states, not with events × objects as :func:`replay`'s do."""
    scene = dict(start) if isinstance(start, Mapping) else start_scene(start)
    for event in events:
        states = _states(event)
        if states is not None:
            _put(scene, states)
    return scene


def scene_at(start: Iterable[dict] | Scene, events: Sequence[Mapping], t: float) -> Scene:
    """The scene at client time ``t`` (ms): after the events, in seq order, up to the first that the clock puts
    after ``t`` (a clock that stepped back after a reload never reorders events)."""
    upto, latest = 0, -math.inf
    for i, e in enumerate(events):
        latest = max(latest, e["t"])
        if latest > t:
            break
        upto = i + 1
    return final_scene(start, events[:upto])


def differences(replayed: Scene, submitted: Iterable[dict], tolerance: float = TOLERANCE) -> list[str]:
    """How a replayed scene differs from a submitted one (empty when they are the same): objects only one has,
    and fields that differ (numbers by more than ``tolerance``)."""
    theirs = start_scene(submitted)
    out = [f"{i}: only in the replay" for i in sorted(set(replayed) - set(theirs))]
    out += [f"{i}: only in the submitted scene" for i in sorted(set(theirs) - set(replayed))]
    for i in sorted(set(replayed) & set(theirs)):
        a, b = replayed[i], theirs[i]
        for key in sorted(set(a) | set(b)):
            if not _same(a.get(key), b.get(key), tolerance):
                out.append(f"{i}: {key} differs")
    return out


def _same(a, b, tolerance: float) -> bool:
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y, tolerance) for x, y in zip(a, b, strict=True))
    if isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        return math.isclose(a, b, rel_tol=0.0, abs_tol=tolerance)
    return a == b
