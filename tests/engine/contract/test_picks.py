"""One definition of a pick (scenesuggest/contract/picks.py): which picks are final."""

from scenesuggest.contract.picks import picks


def log(*events):
    """Events of one trial from (type, payload) pairs, numbered in order."""
    return [{"seq": i, "t": 1000.0 * i, "type": kind, "trial": 0, "payload": payload}
            for i, (kind, payload) in enumerate(events)]


def pick(kind, obj, rank, replaces=None):
    return (kind, {"object": obj, "model": f"m-{obj}", "category": "Chair", "rank": rank, "source": "context"}
            | ({"replaces": replaces} if replaces else {}))


def finals(events):
    return [(p.object, p.final) for p in picks(events)]


def test_a_suggestion_replaced_in_place_is_not_the_choice_but_the_last_of_the_chain_is():
    events = log(("trial_start", {}), pick("insert", "a-1", 1), pick("replace", "a-2", 3, "a-1"),
                 pick("replace", "a-3", 2, "a-2"), pick("insert", "b-4", 1))
    assert finals(events) == [("a-1", False), ("a-2", False), ("a-3", True), ("b-4", True)]


def test_an_undone_pick_is_not_the_choice_and_an_undone_replace_replaced_nothing():
    steps = [("trial_start", {}), pick("insert", "a-1", 1), pick("replace", "a-2", 3, "a-1"),
             ("undo", {"action": "replace"})]
    assert finals(log(*steps)) == [("a-1", True), ("a-2", False)]  # a-1 is back; a-2 was taken back
    assert finals(log(*steps, ("redo", {"action": "replace"}))) == [("a-1", False), ("a-2", True)]
    moved_first = log(("trial_start", {}), pick("insert", "a-1", 1), pick("replace", "a-2", 3, "a-1"),
                      ("move_end", {"object": "a-2"}), ("undo", {"action": "move"}))
    assert finals(moved_first) == [("a-1", False), ("a-2", True)]  # the undo took back the move only


def test_after_a_reload_the_editor_cannot_undo_what_came_before():
    events = log(("trial_start", {}), pick("insert", "a-1", 1), pick("replace", "a-2", 3, "a-1"),
                 ("resume", {"reason": "reload"}), ("undo", {"action": "replace"}))
    assert finals(events) == [("a-1", False), ("a-2", True)]


def test_an_id_used_again_after_a_reload_is_another_object():
    events = log(("trial_start", {}), pick("insert", "chair-1", 1), ("delete", {"object": "chair-1"}),
                 ("resume", {"reason": "reload"}), pick("insert", "chair-1", 2), pick("replace", "chair-2", 1,
                                                                                      "chair-1"))
    assert finals(events) == [("chair-1", True), ("chair-1", False), ("chair-2", True)]


def test_an_undone_insert_is_no_choice_until_redone():
    steps = [("trial_start", {}), pick("insert", "a-1", 4), ("undo", {"action": "insert"})]
    assert finals(log(*steps)) == [("a-1", False)]
    assert finals(log(*steps, ("redo", {"action": "insert"}))) == [("a-1", True)]


def test_the_analysis_reads_final_as_the_export_does():
    """The report's picks come from the same function over every event, so an undo counts there too."""
    from types import SimpleNamespace

    import pandas as pd

    from analysis.measures import picks_table

    events = log(("trial_start", {}), pick("insert", "a-1", 1), pick("replace", "a-2", 3, "a-1"),
                 ("undo", {"action": "replace"}), pick("insert", "b-3", 2))
    frame = pd.DataFrame([{"participant": 1, "seq": e["seq"], "client_t_ms": e["t"], "type": e["type"],
                           "trial": e["trial"], "payload": e["payload"]} for e in events])
    trials = pd.DataFrame([{"participant": 1, "trial": 0, "complete": True, "condition": "full", "scene": "s"}])
    table = picks_table(SimpleNamespace(events=frame), trials)
    assert list(zip(table["seq"], table["final"], strict=True)) == [(p.seq, p.final) for p in picks(events)]
    assert table["final"].tolist() == [True, False, True]
