"""What every command of the ``scenesuggest`` family prints and takes alike: one JSON document or a line for a
person (:func:`emit`), a progress bar on stderr (:func:`progress`), and the corpus source and mesh folder options.
Shared by each package's ``cli.py``; it imports no stage."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable

import click

SOURCE_HELP = "stanford:DIR, ai2thor (the installed procthor package data) or json:DIR"

meshes_option = click.option("--meshes", type=click.Path(file_okay=False), default=None,
                             help="Folder of Stanford OBJ meshes (default: DIR/models, ../stanford_models/models "
                                  "or $SCENESUGGEST_STANFORD_MESHES).")


def progress(items: Iterable, label: str = "") -> Iterable:
    """Show a progress bar on stderr while iterating (just the label when stderr is not a terminal)."""
    items = list(items)
    with click.progressbar(items, label=label, file=sys.stderr, show_pos=True) as bar:
        yield from bar


def emit(data: dict, as_json: bool, human: str) -> None:
    """``data`` as one JSON document on stdout with ``as_json``, else ``human``."""
    if as_json:
        click.echo(json.dumps(data, indent=1))
    else:
        click.echo(human)
