"""What a simulated person is like: every behavioural parameter of the bots, named, with its unit, its allowed
range and where its default comes from.

A :class:`Human` is one set of values (the defaults, or a calibration's fit: :mod:`.calibrate`). The operator
times themselves (keystroke, point, button, mental preparation, Fitts' law) stay in :mod:`.timing`; what is here
is what the keystroke-level model leaves out and a person spends most of their seconds on — hesitating, looking
round the scene, scanning lists, choosing search words, misjudged drags and turns, and getting faster with
practice — and how much people and scenes differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

from scenesuggest.errors import SceneSuggestError

from .paper_tables import CONDITIONS as EVERY

LIST, SUGGESTIONS = ("none",), ("basic", "full")


def _p(default: float, unit: str, low: float, high: float, source: str, free: bool = True,
       used: tuple[str, ...] = EVERY) -> float:
    """A parameter's declaration: its default, and its metadata for :func:`describe` and validation. ``used``: the
    conditions whose trials the parameter acts in (a bot in any other condition behaves the same whatever its
    value; a test holds it so), and so the only ones whose numbers can inform it."""
    return field(default=default, metadata={"unit": unit, "low": low, "high": high, "source": source,
                                             "free": free, "used": used})


@dataclass(frozen=True)
class Human:
    """The behaviour of the simulated participants (one set of values for all of them; people differ by
    ``skill_sd`` and scenes by ``scene_sd``). ``free`` parameters are fitted by :mod:`.calibrate` to the paper's
    numbers for the conditions a calibration is given (those of its ``used`` conditions); the others are fixed by
    the interface or the literature."""

    hesitation_s: float = _p(0.5, "s", 0.0, 10.0, "mean pause before each action (exponential); fitted")
    look_round_s: float = _p(1.5, "s", 0.0, 20.0, "mean time looking round the scene (camera orbits) before "
                                                  "placing each object; fitted")
    scan_item_s: float = _p(0.35, "s", 0.05, 3.0, "looking at one thumbnail of a list (visual search, about "
                                                  "0.3 s per item; Card, Moran & Newell 1983); fitted")
    list_patience: float = _p(24.0, "items", 1.0, 400.0, "items of the fixed model list a person scans before "
                                                         "searching instead; fitted", used=LIST)
    search_first: float = _p(0.3, "probability", 0.0, 1.0, "chance of typing a search before scanning the "
                                                           "model list; fitted", used=LIST)
    overlook: float = _p(0.2, "probability", 0.0, 0.9, "mean chance of missing the wanted model in a list "
                                                       "while looking at it (per person: Beta, strength 10); "
                                                       "fitted")
    category_words: float = _p(0.5, "probability", 0.0, 1.0, "chance that a search uses the category's words "
                                                             "(else words of the model's name and tags); fitted")
    generic_words: float = _p(0.3, "probability", 0.0, 1.0, "chance that a person types only the category's "
                                                            "head noun first (lamp for a desk lamp); fitted")
    tag_words: float = _p(0.2, "probability", 0.0, 1.0, "chance that a person's own words for an object are one "
                                                        "word of what it is for or looks like (a tag several models "
                                                        "share), not its name; fitted")
    unknown_words: float = _p(0.2, "probability", 0.0, 1.0, "chance that a person's first search for an object uses "
                                                            "a word the library does not know (a typo, their own word "
                                                            "for it): they look, and try again; fitted")
    drag_error: float = _p(0.3, "fraction", 0.0, 2.0, "standard deviation of where a drag ends, as a fraction of "
                                                      "its distance (each miss is corrected by another drag); "
                                                      "fitted")
    drag_settle_s: float = _p(1.0, "s", 0.0, 30.0, "mean time a drag is held while fine-positioning and "
                                                   "watching (exponential), beyond its Fitts' law time; fitted")
    turn_settle_s: float = _p(1.0, "s", 0.0, 30.0, "mean time a turn is held while watching the heading "
                                                   "(exponential), beyond its key presses; fitted")
    turn_overshoot_deg: float = _p(15.0, "deg per 90 deg", 0.0, 120.0, "standard deviation of how far a turn goes "
                                                                       "past (or short of) the wanted heading, "
                                                                       "per 90 degrees turned; fitted")
    practice: float = _p(0.3, "fraction", 0.0, 3.0, "extra time on a person's first trial, as a fraction of "
                                                    "their practised time; fitted")
    practice_halving: float = _p(2.0, "trials", 0.5, 20.0, "trials after which the practice extra halves "
                                                           "(power law of practice, Newell & Rosenbloom 1981)",
                                 free=False)
    suggestion_patience: float = _p(12.0, "items", 1.0, 100.0, "suggestions looked at before searching: the "
                                                               "panel shows 3 x 4 tiles without scrolling; "
                                                               "fitted", used=SUGGESTIONS)
    results_scanned: float = _p(12.0, "items", 1.0, 200.0, "search results looked at before reformulating: "
                                                           "the panel's first screen", free=False)
    reformulations: float = _p(3.0, "searches", 0.0, 10.0, "new search texts tried after the first before giving "
                                                           "up on an object", free=False)
    position_tolerance_m: float = _p(0.03, "m", 0.001, 1.0, "how close a person drags before they are "
                                                            "satisfied (the target shown beside, at this scale)",
                                     free=False)
    turn_tolerance_deg: float = _p(4.0, "deg", 0.5, 45.0, "how close a person turns before they are satisfied",
                                   free=False)
    skill_sd: float = _p(0.25, "log s", 0.0, 2.0, "spread of people's speed: log-normal standard deviation of a "
                                                  "person's time factor; fitted to the paper's intervals")
    scene_sd: float = _p(0.15, "log s", 0.0, 2.0, "spread of scenes' difficulty: log-normal standard deviation of "
                                                  "a scene's time factor, the same for everyone; fitted to the "
                                                  "paper's intervals")
    trackpad_share: float = _p(0.2, "probability", 0.0, 1.0, "share of people who drag with a trackpad (the paper "
                                                             "notes some did); fitted to the paper's intervals")
    trackpad_slowdown: float = _p(1.7, "factor", 1.0, 5.0, "how much longer a drag takes on a trackpad than with a "
                                                           "mouse: pointing throughput 2.9 against 4.9 bits/s "
                                                           "(MacKenzie, Kauppinen & Silfverberg 2001)", free=False)

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise SceneSuggestError(f"expected a number, got {value!r}", field=f.name)
            if not math.isfinite(value):
                raise SceneSuggestError(f"expected a finite number, got {value!r}", field=f.name)
            low, high = f.metadata["low"], f.metadata["high"]
            if not low <= value <= high:
                raise SceneSuggestError(f"{value!r} is outside [{low}, {high}] ({f.metadata['unit']})",
                                        field=f.name)

    def practice_factor(self, played: int) -> float:
        """How much slower than practised a person is on their trial number ``played`` (0 = the first)."""
        return 1.0 + self.practice * 0.5 ** (played / self.practice_halving)

    def with_values(self, values: dict[str, float]) -> Human:
        """These parameters with ``values`` (name → value) replaced; an unknown name is an error."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise SceneSuggestError(f"no behaviour parameter {unknown[0]!r} (known: {', '.join(sorted(known))})",
                                    field=unknown[0])
        return replace(self, **{k: float(v) if isinstance(v, int | float) and not isinstance(v, bool) else v
                                for k, v in values.items()})

    def values(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


def free_parameters(conditions: tuple[str, ...] = EVERY) -> list[str]:
    """The names of the parameters a calibration on ``conditions`` fits (free, and used in one of them), in
    declaration order."""
    return [f.name for f in fields(Human) if f.metadata["free"] and set(f.metadata["used"]) & set(conditions)]


def used_in(name: str) -> tuple[str, ...]:
    """The conditions whose trials parameter ``name`` acts in."""
    return {f.name: f for f in fields(Human)}[name].metadata["used"]


def bounds(name: str) -> tuple[float, float]:
    f = {f.name: f for f in fields(Human)}[name]
    return f.metadata["low"], f.metadata["high"]


def describe(human: Human | None = None) -> list[dict]:
    """Every parameter: name, value, unit, range, free, and where its default comes from."""
    human = human or Human()
    return [{"name": f.name, "value": getattr(human, f.name), "default": f.default, "unit": f.metadata["unit"],
             "low": f.metadata["low"], "high": f.metadata["high"], "free": f.metadata["free"],
             "used": list(f.metadata["used"]), "source": f.metadata["source"]} for f in fields(Human)]
