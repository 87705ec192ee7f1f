"""Trials: events ingested and stored, the lists shown, the scenes the editor posts, replays and the check of a
finished trial."""
