"""Balanced orders: Williams designs for conditions, Latin squares for scenes, and each participant's plan.

A schedule *row* is what assignment balances: for the ``williams`` design, one row per (Williams row,
period); ``random`` and ``fixed`` designs have one row per period.
"""

from __future__ import annotations

import random
from dataclasses import dataclass


def williams_square(n: int) -> list[list[int]]:
    """Rows of condition indices 0..n−1: n rows for even n, 2n for odd n.

    Every condition appears once per row and once per position in each n×n square; every ordered pair of
    different conditions is adjacent equally often (once for even n, twice for odd n).
    """
    if not isinstance(n, int) or n < 1:
        raise ValueError("n must be a positive integer")
    first, low, high = [0], 1, n - 1
    while len(first) < n:
        first.append(low)
        low += 1
        if len(first) < n:
            first.append(high)
            high -= 1
    rows = [[(c + i) % n for c in first] for i in range(n)]
    if n % 2 == 1:
        rows += [list(reversed(r)) for r in rows]
    return rows


def latin_square(n: int) -> list[list[int]]:
    """The cyclic n×n Latin square: row i is (i, i+1, …) mod n."""
    return [[(i + j) % n for j in range(n)] for i in range(n)]


@dataclass(frozen=True)
class PlannedTrial:
    index: int  # −1 for the practice trial, then 0, 1, …
    kind: str  # "practice" | "trial"
    condition: str
    scene: str
    period: int
    block: int


def condition_orders(kind: str, n_conditions: int) -> list[list[int]]:
    if kind == "williams":
        return williams_square(n_conditions)
    return [list(range(n_conditions))]


def n_rows(kind: str, n_conditions: int, n_periods: int) -> int:
    return len(condition_orders(kind, n_conditions)) * n_periods


def plan(kind: str, blocking: str, conditions: list[str], periods: list[list[str]], row: int,
         seed: int = 0, practice: tuple[str, str] | None = None) -> list[PlannedTrial]:
    """The trials of a participant in schedule ``row``: every (condition, scene of the row's period) pair once.

    ``blocking="condition"``: one block per condition in the row's order, the period's scenes within a
    block in the order of a Latin-square row that shifts with the block, so that each scene takes each
    position once. ``blocking="scene"``: one block per scene, the conditions within it in the row's order.
    ``random`` designs draw the condition order from ``seed``.
    """
    orders = condition_orders(kind, len(conditions))
    order_index, period = row % len(orders), row // len(orders)
    order = list(orders[order_index])
    if kind == "random":
        random.Random(seed).shuffle(order)
    scenes = periods[period]
    latin = latin_square(len(scenes))
    trials: list[PlannedTrial] = []
    if practice:
        trials.append(PlannedTrial(-1, "practice", practice[1], practice[0], period, -1))
    if blocking == "condition":
        for b, c in enumerate(order):
            for s in latin[(b + order_index) % len(scenes)]:
                trials.append(PlannedTrial(len(trials) - bool(practice), "trial", conditions[c], scenes[s], period, b))
    else:
        for b, s in enumerate(latin[order_index % len(scenes)]):
            for c in order:
                trials.append(PlannedTrial(len(trials) - bool(practice), "trial", conditions[c], scenes[s], period, b))
    return trials
