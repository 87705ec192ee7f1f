"""WordNet 3.0 nouns, read from the database files of Debian's ``wordnet-base`` (``/usr/share/wordnet``).

Only what naming a category needs: the noun senses of a lemma (most frequent first), a sense's lemmas and its
hypernyms. The files are read in the documented database format (``wndb(5)``: ``index.noun`` lists a lemma's
synset offsets, ``data.noun`` holds each synset at the byte offset that names it); nltk's reader cannot be used on
them because it also requires the ``lexnames`` file, which ``wordnet-base`` does not ship.

A synset is named by ShapeNetSem's spelling of it, ``n`` and its offset (``n03001627`` — ShapeNetSem drops the
leading zero: ``n3001627``; :func:`synset_id` accepts both).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from ..errors import SceneSuggestError

#: Where Debian's wordnet-base puts the database; ``SCENESUGGEST_WORDNET`` names another folder.
DEFAULT_DIR = "/usr/share/wordnet"
#: physical_entity.n.01: a sense is a thing (not an act, a group, a writing…) when this is among its hypernyms.
PHYSICAL_ENTITY = "n00001930"


@dataclass(frozen=True)
class Synset:
    id: str  # "n03001627"
    lemmas: tuple[str, ...]  # "armchair", "garbage_can" (lower case, words joined by "_")
    hypernyms: tuple[str, ...]  # ids, the instance-of links too
    gloss: str


def synset_id(text: str) -> str:
    """A noun synset id in full (``n3001627`` → ``n03001627``); raises on anything else."""
    digits = text[1:] if text[:1] == "n" else ""
    if not digits.isdigit() or len(digits) > 8:
        raise SceneSuggestError(f"not a WordNet noun synset: {text!r}", field="wnsynset")
    return "n" + digits.zfill(8)


class WordNet:
    """The noun part of a WordNet database folder."""

    def __init__(self, directory: str | Path | None = None):
        self.directory = Path(directory or os.environ.get("SCENESUGGEST_WORDNET") or DEFAULT_DIR)
        index, data = self.directory / "index.noun", self.directory / "data.noun"
        if not (index.is_file() and data.is_file()):
            raise SceneSuggestError(f"WordNet 3.0 is not installed in {self.directory} (no index.noun and data.noun): "
                                    "apt-get install wordnet-base, or set SCENESUGGEST_WORDNET to its folder",
                                    file=str(self.directory))
        self._senses: dict[str, tuple[str, ...]] = {}
        with index.open(encoding="utf-8") as f:
            for line in f:
                if line.startswith(" "):  # the licence
                    continue
                fields = line.split()
                count = int(fields[2])
                self._senses[fields[0]] = tuple("n" + o for o in fields[len(fields) - count:])
        self._data = data.read_bytes()
        self._synsets: dict[str, Synset] = {}

    def senses(self, lemma: str) -> tuple[str, ...]:
        """The noun synsets of ``lemma`` (any case; words joined by ``_`` or spaces), most frequent first; a plural
        also finds its singular (``curtains`` → ``curtain``)."""
        word = "_".join(lemma.lower().split())
        found = self._senses.get(word)
        if found:
            return found
        for suffix, base in (("ies", "y"), ("es", ""), ("s", "")):
            if word.endswith(suffix) and len(word) > len(suffix) + 2:
                found = self._senses.get(word[: -len(suffix)] + base)
                if found:
                    return found
        return ()

    def synset(self, sid: str) -> Synset:
        """The synset ``sid`` (``n03001627`` or ShapeNetSem's ``n3001627``)."""
        sid = synset_id(sid)
        cached = self._synsets.get(sid)
        if cached is not None:
            return cached
        start = int(sid[1:])
        end = self._data.find(b"\n", start)
        line = self._data[start:end].decode("utf-8") if 0 <= start < len(self._data) else ""
        if not line.startswith(sid[1:]):
            raise SceneSuggestError(f"no WordNet noun synset {sid}", field="wnsynset")
        head, _, gloss = line.partition(" | ")
        fields = head.split()
        words = int(fields[3], 16)
        lemmas = tuple(fields[4 + 2 * k].lower() for k in range(words))
        at = 4 + 2 * words
        pointers = int(fields[at])
        hypernyms = tuple("n" + fields[at + 2 + 4 * k] for k in range(pointers)
                          if fields[at + 1 + 4 * k] in ("@", "@i") and fields[at + 3 + 4 * k] == "n")
        out = Synset(sid, lemmas, hypernyms, gloss.strip())
        self._synsets[sid] = out
        return out

    def ancestors(self, sid: str) -> list[tuple[str, int]]:
        """Every hypernym of ``sid`` with its distance (1: a direct hypernym), nearest first, each once."""
        out, seen, frontier, depth = [], {synset_id(sid)}, [synset_id(sid)], 0
        while frontier:
            depth += 1
            nxt = []
            for s in frontier:
                for h in self.synset(s).hypernyms:
                    if h not in seen:
                        seen.add(h)
                        out.append((h, depth))
                        nxt.append(h)
            frontier = nxt
        return out

    def depth(self, sid: str) -> int:
        """The longest chain of hypernyms from ``sid`` up to WordNet's root (entity.n.01: 0)."""
        return max((d for _, d in self.ancestors(sid)), default=0)

    def is_thing(self, sid: str) -> bool:
        """Whether ``sid`` names a physical thing (physical_entity.n.01 is among its hypernyms)."""
        return any(h == PHYSICAL_ENTITY for h, _ in self.ancestors(sid))


@cache
def wordnet() -> WordNet:
    """The machine's WordNet (read once)."""
    return WordNet()
