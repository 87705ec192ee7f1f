"""Participants: arrival and assignment, the device check, their progress through a study, the editor's boot data,
how their sessions ended, and pilots."""
