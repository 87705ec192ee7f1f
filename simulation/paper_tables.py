"""The paper's numbers the simulated participants are fitted to and judged by (Savva, Chang, Agrawala:
SceneSuggest, Table 1 and Table 2; 20 participants × 9 trials, a 102-model library), by condition.

Table 1 gives per-trial means with 95% bootstrap intervals (seconds, keyword queries, MRR); an interval's width
also says how much people differ. Table 2 gives the share of picks at rank 1, 2, 3 and 4 or lower, with no
interval. :func:`cells` hands out the cells of some conditions only:
a calibration that leaves a condition out asks for the others' cells and never holds the held-out numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

from scenesuggest.errors import SceneSuggestError

CONDITIONS = ("none", "basic", "full")
#: Table 1: measure → condition → (mean, low, high).
TABLE1 = {
    "total_time": {"none": (204.0, 177.0, 241.0), "basic": (170.0, 130.0, 267.0), "full": (139.0, 118.0, 168.0)},
    "rotation_time": {"none": (23.6, 19.9, 28.7), "basic": (22.4, 19.5, 26.5), "full": (17.2, 14.3, 21.1)},
    "translation_time": {"none": (40.5, 32.0, 51.1), "basic": (38.5, 31.0, 50.1), "full": (39.8, 30.1, 62.5)},
    "n_text_queries": {"none": (5.2, 3.8, 7.0), "basic": (3.3, 2.3, 4.9), "full": (2.5, 1.6, 3.9)},
    "mrr": {"none": (0.353, 0.318, 0.388), "basic": (0.785, 0.765, 0.805), "full": (0.769, 0.747, 0.791)},
}
#: Table 2: rank label → condition → share of final picks.
TABLE2 = {
    "1": {"none": 0.296, "basic": 0.687, "full": 0.675},
    "2": {"none": 0.140, "basic": 0.111, "full": 0.0984},
    "3": {"none": 0.0035, "basic": 0.0428, "full": 0.0487},
    "4+": {"none": 0.560, "basic": 0.159, "full": 0.178},
}
#: Table 2 gives no interval: a share off by 5 points costs one standard error in a fit, and a predicted share
#: within RANK_TOLERANCE of the paper's matches it.
RANK_SE, RANK_TOLERANCE = 0.05, 0.08
#: The paper's participants, and the times whose intervals say how much people and scenes differ: a mean's standard
#: error over PARTICIPANTS people is its interval's width / 3.92, known to within SPREAD_RELATIVE_SE of itself (the
#: standard deviation of 20 people's is 16% uncertain; the bootstrap adds its own). This reads the paper's
#: bootstrap as resampling participants (as our analysis does); the paper does not say.
PARTICIPANTS = 20
SPREAD_MEASURES = ("total_time", "rotation_time", "translation_time")
SPREAD_RELATIVE_SE = 0.2


def interval_se(low: float, high: float) -> float:
    """The standard error a 95% interval (``low``, ``high``) gives: its width / 3.92."""
    return (high - low) / (2 * 1.96)


@dataclass(frozen=True)
class Cell:
    """One number of the paper in ``condition``: a Table 1 mean (``kind`` "mean", with its 95% interval), a Table
    2 share (``measure`` ``rank_1`` … ``rank_4+``, "share") or the standard error of a Table 1 time over the paper's
    participants (``measure`` e.g. ``total_time_se``, "spread", from the interval's width); ``se`` is what a fit
    weighs it by (the interval's width / 3.92, RANK_SE, or SPREAD_RELATIVE_SE of the spread)."""

    kind: str
    measure: str
    condition: str
    mean: float
    low: float | None = None
    high: float | None = None
    fixed_se: float | None = None  # a standard error of its own (a drawn cell keeps the paper's)

    @property
    def table(self) -> int | None:
        return {"mean": 1, "share": 2}.get(self.kind)

    @property
    def se(self) -> float:
        if self.fixed_se is not None:
            return self.fixed_se
        if self.kind == "mean":
            return interval_se(self.low, self.high)
        return RANK_SE if self.kind == "share" else SPREAD_RELATIVE_SE * self.mean

    @property
    def key(self) -> str:
        return f"{self.condition}.{self.measure}"

    def matched(self, value: float) -> bool:
        """Whether a simulated ``value`` matches this cell: inside the paper's interval (a mean), within
        RANK_TOLERANCE of its share, within two of its standard errors (a spread)."""
        if self.kind == "mean":
            return self.low <= value <= self.high
        if self.kind == "share":
            return abs(value - self.mean) <= RANK_TOLERANCE
        return abs(value - self.mean) <= 2 * self.se


def conditions_of(text: str | list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """The conditions a fold is fitted on, from ``none,basic`` (or a list), in the paper's order. One or two
    conditions: a fold leaves at least one out to predict. Errors name what is wrong."""
    names = [c.strip() for c in (text.split(",") if isinstance(text, str) else text)]
    if not names or any(not c for c in names):
        raise SceneSuggestError(f"expected conditions separated by commas (of {', '.join(CONDITIONS)}), "
                                f"got {text!r}", field="on")
    unknown = [c for c in names if c not in CONDITIONS]
    if unknown:
        raise SceneSuggestError(f"no condition {unknown[0]!r} in the paper (it has {', '.join(CONDITIONS)})",
                                field="on")
    if len(set(names)) != len(names):
        raise SceneSuggestError(f"a condition is named twice in {text!r}", field="on")
    if len(names) == len(CONDITIONS):
        raise SceneSuggestError("a calibration fitted on all three conditions predicts none: name one or two "
                                "and leave the rest out", field="on")
    return tuple(c for c in CONDITIONS if c in names)


def cells(conditions: tuple[str, ...], spreads: bool = True) -> tuple[Cell, ...]:
    """Every cell of Table 1 and Table 2 in ``conditions`` (and no other condition's), then (``spreads``) the
    spreads their times' intervals give."""
    out = [Cell("mean", measure, c, *by[c]) for measure, by in TABLE1.items() for c in conditions]
    out += [Cell("share", f"rank_{label}", c, by[c]) for label, by in TABLE2.items() for c in conditions]
    if spreads:
        out += [Cell("spread", f"{m}_se", c, interval_se(*TABLE1[m][c][1:])) for m in SPREAD_MEASURES
                for c in conditions]
    return tuple(out)


def held_out(conditions: tuple[str, ...]) -> tuple[str, ...]:
    """The conditions a fold fitted on ``conditions`` predicts."""
    return tuple(c for c in CONDITIONS if c not in conditions)
