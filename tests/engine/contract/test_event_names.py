"""Every event type the server, the simulation and the analysis name is one the vocabulary defines: a literal
compared with an event's type (``e["type"] == …``, ``Event.type.in_(…)``, ``kinds == …`` and any name bound from
those), or given to the functions that log an event (the bots' ``event``/``change``), is checked against
:data:`scenesuggest.contract.events.VOCABULARY`, so a renamed or misspelt type fails here instead of silently matching
nothing."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from scenesuggest.contract.events import VOCABULARY

ROOT = Path(__file__).resolve().parents[3]
#: What reads an event's type: a subscript ``["type"]``, an attribute ``.type`` (a row's), the analysis' array of
#: types (``kinds``).
TYPE = re.compile(r"\[['\"]type['\"]\]|\.type\b|\bkinds\b")
#: Calls whose first argument is the type of the event they log (simulation/actions.py).
LOGGERS = ("event", "change")
#: Modules whose "type" is something else's, with what it is.
OTHER_TYPES = {"study_server/backup.py": "a database column's type",
               "scenesuggest/learning/priors.py": "the entries of a priors file",
               "study_server/export_schema.py": "an export column's Table Schema type"}


def _literals(node) -> list[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [s for e in node.elts for s in _literals(e)]
    return []


def _bound(scope: ast.AST) -> set[str]:
    """Names in ``scope`` bound from an event's type: ``kind = e["type"]``, ``p, kind = e["payload"], e["type"]``
    and ``for kind, p in zip(kinds, …)``."""
    names = set()
    for n in ast.walk(scope):
        pairs = []
        if isinstance(n, ast.Assign):
            for target in n.targets:
                if isinstance(target, ast.Tuple) and isinstance(n.value, ast.Tuple):
                    pairs += zip(target.elts, n.value.elts, strict=False)
                else:
                    pairs.append((target, n.value))
        elif isinstance(n, ast.For) and isinstance(n.target, ast.Tuple) and isinstance(n.iter, ast.Call) \
                and getattr(n.iter.func, "id", "") == "zip":
            pairs += zip(n.target.elts, n.iter.args, strict=False)
        names |= {t.id for t, v in pairs if isinstance(t, ast.Name) and TYPE.search(ast.unparse(v))}
    return names


def _reads(expr: ast.AST, names: set[str]) -> bool:
    text = ast.unparse(expr)
    return bool(TYPE.search(text)) or any(re.search(rf"\b{re.escape(n)}\b", text) for n in names)


def event_type_literals(path: Path) -> list[tuple[str, int]]:
    """The event-type literals of ``path``, with their lines."""
    tree = ast.parse(path.read_text())
    found = []
    scopes = [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))]
    for scope in [tree, *scopes]:
        names = _bound(scope)
        for n in ast.walk(scope):
            if isinstance(n, ast.Compare) and any(_reads(s, names) for s in [n.left, *n.comparators]):
                found += [(s, n.lineno) for side in [n.left, *n.comparators] for s in _literals(side)]
            elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute):
                if n.func.attr in ("in_", "isin") and _reads(n, names):
                    found += [(s, n.lineno) for a in n.args for s in _literals(a)]
                elif n.func.attr in LOGGERS and n.args and path.parent.name == "simulation":
                    found += [(s, n.lineno) for s in _literals(n.args[0])]
    return sorted(set(found))


def test_every_event_type_named_outside_the_vocabulary_is_in_it():
    checked, unknown = 0, []
    for package in ("study_server", "simulation", "analysis", "scenesuggest"):
        for path in (ROOT / package).rglob("*.py"):
            if str(path.relative_to(ROOT)) in OTHER_TYPES:
                continue
            for literal, line in event_type_literals(path):
                checked += 1
                if literal not in VOCABULARY:
                    unknown.append(f"{path.relative_to(ROOT)}:{line}: {literal!r}")
    assert not unknown, "event types the vocabulary does not define:\n" + "\n".join(unknown)
    assert checked > 40  # the readers are found: measures, replays, picks, the bots, the flow's work check


def test_a_misspelt_type_is_found(tmp_path):
    path = tmp_path / "reader.py"
    path.write_text('def f(events, kinds):\n    p, kind = events[0]["payload"], events[0]["type"]\n'
                    '    return kind == "move_ended", kinds == "trial_done", [e for e in events if e["type"] in '
                    '("undo", "redoo")]\n')
    assert sorted(s for s, _ in event_type_literals(path)) == ["move_ended", "redoo", "trial_done", "undo"]
