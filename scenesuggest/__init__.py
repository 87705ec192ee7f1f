"""SceneSuggest engine, in stages: scenes (with frames, poses, surfaces and the taxonomy), the trial contract, the
model library and its search, corpora, assets, learning (the priors), suggestion, engines by name and their
evaluation.

A pure library: importing it reads no files and opens no databases.
"""

__version__ = "0.1.0"
