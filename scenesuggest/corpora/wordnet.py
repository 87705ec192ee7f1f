"""WordNet 3.0 nouns, read from the database files of Debian's ``wordnet-base`` (``/usr/share/wordnet``).

Only what naming a category needs: the noun senses of a lemma (most frequent first; a plural found through WordNet's
exceptions and its suffix rules, as its own ``morphy`` does), a sense's lemmas and its hypernyms.
The files are read in the documented database format (``wndb(5)``: ``index.noun`` lists a lemma's
synset offsets, ``data.noun`` holds each synset at the byte offset that names it); nltk's reader cannot be used on
them because it also requires the ``lexnames`` file, which ``wordnet-base`` does not ship.

A synset is named ``n`` and its offset in WordNet 3.0 (``n03001627``; :func:`synset_id` also takes it without the
leading zero). ShapeNetSem's ``wnsynset`` spells its ids so but counts in WordNet 3.1 (its chairs say ``n3005231``),
so its models are matched through their lemmas instead (:mod:`scenesuggest.corpora.crosswalk`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from ..errors import SceneSuggestError

#: Where Debian's wordnet-base puts the database; ``SCENESUGGEST_WORDNET`` names another folder.
DEFAULT_DIR = "/usr/share/wordnet"
#: physical_entity.n.01: a sense is a thing (not an act, a group, a feeling…) when this is among its hypernyms.
PHYSICAL_ENTITY = "n00001930"
#: entity.n.01, the root of the nouns.
ROOT = "n00001740"
#: WordNet's suffix rules for nouns, in its order (after the exceptions of ``noun.exc``).
PLURAL_SUFFIXES = (("s", ""), ("ses", "s"), ("xes", "x"), ("zes", "z"), ("ches", "ch"), ("shes", "sh"),
                   ("men", "man"), ("ies", "y"))


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
            for number, line in enumerate(f, start=1):
                if line.startswith(" "):  # the licence
                    continue
                fields = line.split()
                try:
                    count = int(fields[2])
                    offsets = fields[len(fields) - count:]
                    if not count or not all(o.isdigit() for o in offsets):
                        raise ValueError
                except (IndexError, ValueError):
                    raise SceneSuggestError("not a WordNet index line", file=str(index), line=number) from None
                self._senses[fields[0]] = tuple("n" + o for o in offsets)
        self._exceptions: dict[str, list[str]] = {}
        exc = self.directory / "noun.exc"
        if exc.is_file():
            for line in exc.read_text(encoding="utf-8").splitlines():
                inflected, *bases = line.split()
                self._exceptions.setdefault(inflected, []).extend(bases)
        self._data = data.read_bytes()
        self._synsets: dict[str, Synset] = {}
        self._ancestors: dict[str, list[tuple[str, int]]] = {}

    def senses(self, lemma: str) -> tuple[str, ...]:
        """The noun synsets of ``lemma`` (any case; words joined by ``_`` or spaces), most frequent first, then those
        of its base forms (``curtains`` → ``curtain``; ``glasses`` → spectacles, then glass): the word itself, the
        exceptions of ``noun.exc``, then every suffix rule that gives a lemma, each synset once."""
        word = "_".join(lemma.lower().split())
        forms = [word, *self._exceptions.get(word, [])]
        forms += [word[: -len(suffix)] + base for suffix, base in PLURAL_SUFFIXES
                  if word.endswith(suffix) and len(word) > len(suffix)]
        found = [sid for form in forms for sid in self._senses.get(form, ())]
        return tuple(dict.fromkeys(found))

    def synset(self, sid: str) -> Synset:
        """The synset ``sid`` (``n03001627`` or ShapeNetSem's ``n3001627``)."""
        sid = synset_id(sid)
        cached = self._synsets.get(sid)
        if cached is not None:
            return cached
        start = int(sid[1:])
        end = self._data.find(b"\n", start)
        end = len(self._data) if end < 0 else end
        starts_line = 0 < start < len(self._data) and self._data[start - 1:start] == b"\n"
        line = self._data[start:end].decode("utf-8", errors="replace") if starts_line else ""
        if not line.startswith(sid[1:] + " "):
            raise SceneSuggestError(f"no WordNet noun synset {sid}", field="wnsynset")
        head, _, gloss = line.partition(" | ")
        fields = head.split()
        try:
            words = int(fields[3], 16)
            lemmas = tuple(fields[4 + 2 * k].lower() for k in range(words))
            at = 4 + 2 * words
            pointers = int(fields[at])
            hypernyms = tuple("n" + fields[at + 2 + 4 * k] for k in range(pointers)
                              if fields[at + 1 + 4 * k] in ("@", "@i") and fields[at + 3 + 4 * k] == "n")
        except (IndexError, ValueError):
            raise SceneSuggestError(f"not a WordNet synset line at offset {start}",
                                    file=str(self.directory / "data.noun")) from None
        out = Synset(sid, lemmas, hypernyms, gloss.strip())
        self._synsets[sid] = out
        return out

    def ancestors(self, sid: str) -> list[tuple[str, int]]:
        """Every hypernym of ``sid`` with its distance (1: a direct hypernym), nearest first, each once."""
        sid = synset_id(sid)
        if sid not in self._ancestors:
            self._ancestors[sid] = self._walk_up(sid)
        return self._ancestors[sid]

    def _walk_up(self, sid: str) -> list[tuple[str, int]]:
        out, seen, frontier, depth = [], {sid}, [sid], 0
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
        """The fewest hypernym links from ``sid`` up to WordNet's root, entity.n.01 (the root: 0)."""
        return dict(self.ancestors(sid)).get(ROOT, 0)

    def is_thing(self, sid: str) -> bool:
        """Whether ``sid`` names a physical thing (physical_entity.n.01 is among its hypernyms)."""
        return any(h == PHYSICAL_ENTITY for h, _ in self.ancestors(sid))


@cache
def wordnet() -> WordNet:
    """The machine's WordNet (read once)."""
    return WordNet()
