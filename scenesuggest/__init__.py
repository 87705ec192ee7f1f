"""SceneSuggest engine: scenes, corpora, taxonomy, geometry, model library, search and priors.

A pure library: importing it reads no files and opens no databases.
"""

__version__ = "0.1.0"
