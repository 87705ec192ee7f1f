"""The trial contract the client, the server and the analysis share: the event vocabulary and its JSON Schema, a trial
rebuilt from its events, picks, how close a scene came to its target, pose errors, spreadsheet-safe cells."""
