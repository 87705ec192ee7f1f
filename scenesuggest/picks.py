"""What a participant picked from a list: one definition, for the export's ``picks.csv`` and the analysis.

A pick is an ``insert`` or ``replace`` event: the model chosen, its category, the 1-based rank it had in the list
it came from (none for a model placed otherwise), the list's source (``fixed`` list, ``search``, ``context``
suggestions) and the list's id. A pick is *final* unless a later ``replace`` of the same trial replaced its
object in place: the editor places the top suggestion at once, and when the participant swaps it for another
suggestion, the participant's choice is the last pick of that chain (a replace that was undone replaced nothing).
MRR and the rank distribution count final picks only.
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


def picks(events: Iterable[Mapping]) -> list[Pick]:
    """The picks among one participant's ``events`` (mappings with ``seq``, ``t``, ``type``, ``trial`` and
    ``payload``, in seq order). A replace makes the latest pick of the object it replaces not final; undoing
    the replace (the editor's undo stack, which a page load empties, is followed) makes it final again."""
    chosen: list[Mapping] = []
    latest: dict[tuple, int] = {}  # (trial, object id) → index in chosen of the pick that placed it last
    replaced: set[int] = set()
    undo: list[tuple[str, int | None]] = []  # (action, index of the pick a replace made not final)
    redo: list[tuple[str, int | None]] = []
    for e in events:
        kind, p = e["type"], e["payload"]
        if kind in ("trial_start", "resume"):  # a page (re)loaded: its editor starts with empty stacks
            undo.clear()
            redo.clear()
        elif kind in UNDOABLE:
            mark = None
            if kind in PICKS:
                if kind == "replace":
                    mark = latest.get((e["trial"], p.get("replaces")))
                    if mark is not None:
                        replaced.add(mark)
                latest[(e["trial"], p.get("object"))] = len(chosen)
                chosen.append(e)
            undo.append((UNDOABLE[kind], mark))
            redo.clear()
        elif kind in ("undo", "redo"):
            source, target = (undo, redo) if kind == "undo" else (redo, undo)
            if source and source[-1][0] == p.get("action"):  # else the log and the stack disagree: leave it
                step = source.pop()
                target.append(step)
                if step[1] is not None:
                    (replaced.discard if kind == "undo" else replaced.add)(step[1])
    return [_pick(e, i not in replaced) for i, e in enumerate(chosen)]


def _pick(e: Mapping, final: bool) -> Pick:
    p = e["payload"]
    return Pick(seq=e["seq"], trial=e["trial"], t=e["t"], action=e["type"], object=p.get("object", ""),
                model=p.get("model", ""), category=p.get("category", ""), rank=p.get("rank") or None,
                source=p.get("source", ""), list_id=p.get("list_id") or None, final=final)
