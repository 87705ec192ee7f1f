"""Williams designs, Latin squares and participants' plans."""

import itertools
import json
import subprocess
import sys
from collections import Counter

import pytest

from study_server.studies.schedule import latin_square, plan, williams_square


@pytest.mark.parametrize("n", range(1, 9))
def test_williams_square_is_balanced(n):
    rows = williams_square(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    for row in rows:
        assert sorted(row) == list(range(n))  # each condition once per row
    for square in (rows[:n], rows[n:]) if n % 2 else (rows,):
        for position in range(n):
            assert sorted(r[position] for r in square) == list(range(n))  # once per position per square
    if n > 1:
        pairs = Counter((a, b) for r in rows for a, b in itertools.pairwise(r))
        assert set(pairs) == {(a, b) for a in range(n) for b in range(n) if a != b}
        assert len(set(pairs.values())) == 1  # every ordered pair adjacent equally often


def test_williams_rejects_nonsense():
    with pytest.raises(ValueError):
        williams_square(0)


def test_latin_square():
    sq = latin_square(4)
    assert all(sorted(r) == [0, 1, 2, 3] for r in sq)
    assert all(sorted(col) == [0, 1, 2, 3] for col in zip(*sq, strict=True))


def test_the_papers_design_every_condition_scene_pair_once():
    conditions, periods = ["none", "basic", "full"], [["a", "b", "c"], ["d", "e", "f"]]
    rows = 6 * 2
    seen_positions = Counter()
    for row in range(rows):
        trials = plan("williams", "condition", conditions, periods, row, practice=("p", "full"))
        assert trials[0].kind == "practice" and trials[0].index == -1
        real = [t for t in trials if t.kind == "trial"]
        assert [t.index for t in real] == list(range(9))
        assert len({(t.condition, t.scene) for t in real}) == 9
        assert {t.scene for t in real} == set(periods[row // 6])
        blocks = [[t.condition for t in real if t.block == b] for b in range(3)]
        assert all(len(set(b)) == 1 for b in blocks)  # blocked by condition
        assert [b[0] for b in blocks] == [conditions[c] for c in williams_square(3)[row % 6]]
        for t in real:
            seen_positions[(t.scene, t.index % 3)] += 1
    # within each block every scene takes every position equally often across rows
    assert len(set(seen_positions.values())) == 1


def test_scene_blocking_and_other_designs():
    trials = plan("williams", "scene", ["x", "y"], [["s1", "s2"]], 1)
    assert [t.scene for t in trials] == ["s2", "s2", "s1", "s1"]
    assert [t.condition for t in trials] == ["y", "x", "y", "x"]
    fixed = plan("fixed", "condition", ["x", "y", "z"], [["s"]], 0)
    assert [t.condition for t in fixed] == ["x", "y", "z"]
    a = [t.condition for t in plan("random", "condition", ["x", "y", "z"], [["s"]], 0, seed=1)]
    b = [t.condition for t in plan("random", "condition", ["x", "y", "z"], [["s"]], 0, seed=1)]
    assert a == b and sorted(a) == ["x", "y", "z"]


def test_schedule_command():
    out = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "schedule", "williams", "3", "--json"],
                         capture_output=True, text=True, check=True).stdout
    doc = json.loads(out)
    assert doc == {"n": 3, "rows": williams_square(3)}
