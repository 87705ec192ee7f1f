"""What a participant picked from a list: one definition, for the export's ``picks.csv`` and the analysis.

A pick is an ``insert`` or ``replace`` event: the model chosen, its category, the 1-based rank it had in the list
it came from (none for a model placed otherwise), the list's source (``fixed`` list, ``search``, ``context``
suggestions) and the list's id. A pick is *final* unless a later ``replace`` of the same trial replaced its
object in place: the editor places the top suggestion at once, and when the participant swaps it for another
suggestion, the participant's choice is the last pick of that chain. A pick that was undone is not final either
(and a replace that was undone replaced nothing). MRR and the rank distribution count final picks only.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass

PICKS = ("insert", "replace")


@dataclass(frozen=True)
class Pick:
    seq: int
    trial: int | None
    t: float  # client ms
    action: str  # insert | replace
    object: str
    model: str
    category: str
    rank: int | None
    source: str
    list_id: str | None
    final: bool

    @property
    def reciprocal_rank(self) -> float | None:
        return 1.0 / self.rank if self.rank else None

    def to_dict(self) -> dict:
        return {**asdict(self), "reciprocal_rank": self.reciprocal_rank}


#: The editor's undoable actions, by the event that logs each (its undo and redo events name the action).
UNDOABLE = {"insert": "insert", "replace": "replace", "delete": "delete", "move_end": "move", "rotate_end": "rotate"}
#: The event types :func:`picks` reads (the others can be left out of what it is given).
PICK_INPUTS = frozenset(UNDOABLE) | {"undo", "redo", "trial_start", "resume"}
#: Of those, the types whose payload it reads (of the others, only the type and trial count).
PICK_PAYLOADS = frozenset(PICKS) | {"undo", "redo"}


def picks(events: Iterable[Mapping]) -> list[Pick]:
    """The picks among one participant's ``events`` (mappings with ``seq``, ``t``, ``type``, ``trial`` and
    ``payload``; every event, in seq order: the undo, redo and page-load events count). A pick is not final when
    a later replace replaced its object in place, or when it was undone; a replace that was undone replaced
    nothing, and a redo brings both back (the editor's undo stack is followed; a page load empties it)."""
    chosen: list[Mapping] = []
    latest: dict[tuple, int] = {}  # (trial, object id) → index in chosen of the pick that placed it last
    replaced: set[int] = set()
    undone: set[int] = set()
    undo: list[tuple[str, int | None, int | None]] = []  # (action, its pick, the pick a replace replaced)
    redo: list[tuple[str, int | None, int | None]] = []
    for e in events:
        kind, p = e["type"], e["payload"]
        if kind in ("trial_start", "resume"):  # a page (re)loaded: its editor starts with empty stacks
            undo.clear()
            redo.clear()
        elif kind in UNDOABLE:
            own = gone = None
            if kind in PICKS:
                if kind == "replace":
                    gone = latest.get((e["trial"], p.get("replaces")))
                    if gone is not None:
                        replaced.add(gone)
                own = latest[(e["trial"], p.get("object"))] = len(chosen)
                chosen.append(e)
            undo.append((UNDOABLE[kind], own, gone))
            redo.clear()
        elif kind in ("undo", "redo"):
            source, target = (undo, redo) if kind == "undo" else (redo, undo)
            if source and source[-1][0] == p.get("action"):  # else the log and the stack disagree: leave it
                step = source.pop()
                target.append(step)
                _, own, gone = step
                if own is not None:
                    (undone.add if kind == "undo" else undone.discard)(own)
                if gone is not None:
                    (replaced.discard if kind == "undo" else replaced.add)(gone)
    return [_pick(e, i not in replaced and i not in undone) for i, e in enumerate(chosen)]


def _pick(e: Mapping, final: bool) -> Pick:
    p = e["payload"]
    return Pick(seq=e["seq"], trial=e["trial"], t=e["t"], action=e["type"], object=p.get("object", ""),
                model=p.get("model", ""), category=p.get("category", ""), rank=p.get("rank") or None,
                source=p.get("source", ""), list_id=p.get("list_id") or None, final=final)
