"""What a participant picked from a list: one definition, for the export's ``picks.csv`` and the analysis.

A pick is an ``insert`` or ``replace`` event: the model chosen, its category, the 1-based rank it had in the list
it came from (none for a model placed otherwise), the list's source (``fixed`` list, ``search``, ``context``
suggestions) and the list's id. A pick is *final* unless a later ``replace`` of the same trial replaced its
object in place: the editor places the top suggestion at once, and when the participant swaps it for another
suggestion, the participant's choice is the last pick of that chain. MRR and the rank distribution count final
picks only.
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


def picks(events: Iterable[Mapping]) -> list[Pick]:
    """The picks among one participant's ``events`` (mappings with ``seq``, ``t``, ``type``, ``trial`` and
    ``payload``, in seq order)."""
    chosen = [e for e in events if e["type"] in PICKS]
    replaced = {(e["trial"], e["payload"].get("replaces")) for e in chosen if e["type"] == "replace"}
    out = []
    for e in chosen:
        p = e["payload"]
        rank = p.get("rank")
        out.append(Pick(seq=e["seq"], trial=e["trial"], t=e["t"], action=e["type"], object=p.get("object", ""),
                        model=p.get("model", ""), category=p.get("category", ""), rank=rank or None,
                        source=p.get("source", ""), list_id=p.get("list_id") or None,
                        final=(e["trial"], p.get("object")) not in replaced))
    return out
