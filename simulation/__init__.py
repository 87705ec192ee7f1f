"""Simulated participants: they take part in a study through its HTTP interface alone (a Flask test client or
real HTTP), never through the server's internals.

- :mod:`.transport` — how requests reach the server (in process, HTTP, a lossy network);
- :mod:`.page` and :mod:`.walker` — the participant walk: pages say their step, one walker goes through them;
- :mod:`.timing` — the keystroke-level model that decides how long each action takes;
- :mod:`.actions` — what a participant does in a trial (rebuild the target from suggestions, lists, search);
- :mod:`.participant` — a whole participant (walk, trials, survey answers, the behaviours that stress a server);
- :mod:`.run` — many participants, one after another, and a summary (``scenesuggest study simulate``).
"""
