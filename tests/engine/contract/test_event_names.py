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
OTHER_TYPES = {"study_server/experimenter/backup.py": "a database column's type",
               "scenesuggest/learning/priors.py": "the entries of a priors file",
               "study_server/experimenter/export_schema.py": "an export column's Table Schema type"}


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


def _constants(tree: ast.Module) -> dict[str, ast.AST]:
    """The module's names bound once at its top level, to what."""
    out = {}
    for n in tree.body:
        targets = n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
        for t in targets:
            if isinstance(t, ast.Name) and getattr(n, "value", None) is not None:
                out[t.id] = n.value
    return out


def _values(node: ast.AST, constants: dict, depth: int = 0) -> list[str]:
    """The strings a collection expression holds, following the module's constants it is built from
    (``frozenset(UNDOABLE) | {"undo"}``: the dict's keys and "undo")."""
    if depth > 8:
        return []
    if isinstance(node, ast.Name) and node.id in constants:
        return _values(constants[node.id], constants, depth + 1)
    if isinstance(node, ast.Dict):
        return [s for k in node.keys if k is not None for s in _values(k, constants, depth + 1)]
    if isinstance(node, ast.Call) and getattr(node.func, "id", "") in ("frozenset", "set", "tuple", "list"):
        return [s for a in node.args for s in _values(a, constants, depth + 1)]
    if isinstance(node, ast.BinOp):
        return _values(node.left, constants, depth + 1) + _values(node.right, constants, depth + 1)
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [s for e in node.elts for s in _values(e, constants, depth + 1)]
    return _literals(node)


def _typed_parameters(tree: ast.Module) -> dict[str, set[int]]:
    """Function name → the positions of its parameters that hold an event type: compared with one, or passed on to
    such a parameter of another function of the module (``interval(start_kind, …)`` → ``kinds == start_kind``)."""
    functions = {f.name: f for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))}
    typed: dict[str, set[int]] = {name: set() for name in functions}

    def holds_a_type(f, p: str) -> bool:
        for n in ast.walk(f):
            if isinstance(n, ast.Compare):
                sides = [n.left, *n.comparators]
                if any(isinstance(x, ast.Name) and x.id == p for x in sides) and any(
                        TYPE.search(ast.unparse(x)) for x in sides if not (isinstance(x, ast.Name) and x.id == p)):
                    return True
            if isinstance(n, ast.Call) and getattr(n.func, "id", None) in typed and any(
                    isinstance(a, ast.Name) and a.id == p and j in typed[n.func.id] for j, a in enumerate(n.args)):
                return True
        return False

    changed = True
    while changed:
        changed = False
        for name, f in functions.items():
            for i, a in enumerate(f.args.args):
                if i not in typed[name] and holds_a_type(f, a.arg):
                    typed[name].add(i)
                    changed = True
    return {name: positions for name, positions in typed.items() if positions}


def event_type_literals(path: Path) -> list[tuple[str, int]]:
    """The event-type literals of ``path``, with their lines: compared with an event's type (directly, through a
    module constant, or given to a function that compares its parameter), or logged by the bots."""
    tree = ast.parse(path.read_text())
    constants, typed = _constants(tree), _typed_parameters(tree)
    found = []
    scopes = [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))]
    for scope in [tree, *scopes]:
        names = _bound(scope)
        for n in ast.walk(scope):
            if isinstance(n, ast.Compare) and any(_reads(s, names) for s in [n.left, *n.comparators]):
                found += [(s, n.lineno) for side in [n.left, *n.comparators] for s in _values(side, constants)]
            elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute):
                if n.func.attr in ("in_", "isin") and _reads(n, names):
                    found += [(s, n.lineno) for a in n.args for s in _values(a, constants)]
                elif n.func.attr in LOGGERS and n.args and path.parent.name == "simulation":
                    found += [(s, n.lineno) for s in _literals(n.args[0])]
            elif isinstance(n, ast.Call) and getattr(n.func, "id", None) in typed:
                found += [(s, n.lineno) for j, a in enumerate(n.args) if j in typed[n.func.id] for s in _literals(a)]
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


def test_types_held_in_constants_or_given_to_helpers_are_found(tmp_path):
    path = tmp_path / "reader.py"
    path.write_text('PICKS = ("insert", "replaced")\nUNDOABLE = {"move_ended": "move"}\n'
                    'INPUTS = frozenset(UNDOABLE) | {"redoo"}\n\n\n'
                    'def between(kinds, start, end):\n    return (kinds == start) | (kinds == end)\n\n\n'
                    'def measure(kinds, events):\n    def interval(a, b):\n        return between(kinds, a, b)\n\n'
                    '    return interval("rotate_start", "rotation_end"), [e for e in events if e["type"] in PICKS],'
                    ' [e for e in events if e.type in INPUTS]\n')
    assert sorted(s for s, _ in event_type_literals(path)) == [
        "insert", "move_ended", "redoo", "replaced", "rotate_start", "rotation_end"]
