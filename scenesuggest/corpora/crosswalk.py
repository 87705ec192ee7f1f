"""Categories mapped from one corpus into another's, so that an engine trained on one can be asked on the other.

Each category of the corpus asked (``test``) is given the category of the training corpus (``train``) that names
the same kind of thing, by the first rule that finds one (its ``via``):

1. ``name`` — the same name, ignoring case and anything but letters and digits (Stanford ``TV`` and a ``Tv``);
2. ``synset`` — the same WordNet noun synset. A category's synsets are the majority synset of its models where its
   corpus labels them (ShapeNetSem's ``wnsynset``, :attr:`ModelInfo.synset`) and the most frequent sense of its
   name that is a physical thing (``GarbageCan`` → garbage_can.n.01, which Stanford's ``TrashBin`` models carry);
3. ``hypernym`` — a training category whose synset is a hypernym of one of the category's, at most
   :data:`MAX_HYPERNYM_DISTANCE` links up, the nearest first (``ArmChair`` → chair.n.01 → ``Chair``);
4. ``head`` — rules 1–3 and 5 on the last word of a compound name (``SideTable`` → table);
5. ``narrower`` — the most common training category one WordNet link or one taxonomy link below the category
   (AI2-THOR's ``Bed`` → Stanford's ``SingleBed``, filed under ``Bed``);
6. ``parent`` — the category's taxonomy parents in its own corpus, nearest first, by a decision or rules 1–2 only
   (Stanford's ``Barstool`` → ``Stool``; a looser match of a parent as broad as "sports equipment" finds shoes).

Where a rule finds several training categories, the one with the most instances is taken. What no rule maps is
*unmapped*: its queries are counted and left out of the figures, and its objects keep their own name, which the
trained engine has never seen (a parent it knows nothing of). :data:`DECISIONS` overrides the rules where they go
wrong, each with its reason; the room shell is always the room shell and a placeholder is never mapped.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, replace

from ..errors import SceneSuggestError
from ..scenes.scene import ROOM, Scene
from ..suggestion.suggestable import suggestable
from .corpus import Corpus
from .wordnet import WordNet, synset_id

#: Hypernym links a ``hypernym`` match may climb (2: armchair → chair; more reaches "seat", "furniture").
MAX_HYPERNYM_DISTANCE = 2
#: A ``hypernym`` match must name something at least this many links below WordNet's root (chair: 9; the
#: "framework" or "structure" some unlabelled Stanford models are named after: 6).
MIN_DEPTH = 7
#: (test corpus kind, category) → the training category (None: unmapped) and why; the rules are wrong there.
DECISIONS: dict[tuple[str, str], tuple[str | None, str]] = {
    # AI2-THOR asked of an engine trained on Stanford
    ("ai2thor", "Window"): (None, "Stanford's rooms have no windows (the hypernym finds 'Framework', a lemma)"),
    ("ai2thor", "CD"): ("CompactDisk", "WordNet's first physical 'cd' is cadmium"),
    ("ai2thor", "CreditCard"): (None, "no cards in Stanford's scenes (the head noun finds 'Paper')"),
    ("ai2thor", "KeyChain"): ("Key", "a ring of keys (the head noun finds a chain)"),
    ("ai2thor", "HandTowelHolder"): (None, "Stanford's 'Holder' holds pens"),
    ("ai2thor", "TowelHolder"): (None, "Stanford's 'Holder' holds pens"),
    ("ai2thor", "ToiletPaperHanger"): (None, "Stanford's 'Hanger' is a coat hanger"),
    ("ai2thor", "ShowerHead"): (None, "Stanford's 'Head' is a human head"),
    ("ai2thor", "ShowerGlass"): (None, "a shower's glass wall (the head noun finds a drinking glass)"),
    ("ai2thor", "LaundryHamper"): ("Basket", "a hamper is a basket (WordNet's first 'hamper' is a fetter)"),
    ("ai2thor", "BathtubBasin"): ("Bathtub", "the basin of a bathtub (the head noun finds a washbasin)"),
    ("ai2thor", "Newspaper"): ("Magazine", "printed pages folded on a table (the parent finds blank paper)"),
    ("ai2thor", "Egg"): ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    ("ai2thor", "Lettuce"): ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    ("ai2thor", "Potato"): ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    ("ai2thor", "Tomato"): ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    ("ai2thor", "DishSponge"): (None, "no sponges in Stanford's scenes (the parent finds 'Utensils')"),
    ("ai2thor", "SaltShaker"): ("PepperMill", "a seasoning dispenser (the parent finds 'Utensils')"),
    ("ai2thor", "PepperShaker"): ("PepperMill", "a seasoning dispenser (the parent finds 'Utensils')"),
    ("ai2thor", "PaperTowelRoll"): ("PaperTowel", "the same roll (the parent finds 'Utensils')"),
    ("ai2thor", "AluminumFoil"): (None, "no foil in Stanford's scenes (the parent finds 'Utensils')"),
    ("ai2thor", "ShelvingUnit"): ("4Shelves", "a stand of shelves (the head noun finds a chain)"),
    ("ai2thor", "CoffeeMachine"): ("CoffeeMaker", "the same machine (the head noun finds a stapler)"),
    ("ai2thor", "WateringCan"): (None, "no watering cans in Stanford's scenes (the head noun finds a soda can)"),
    ("ai2thor", "TeddyBear"): ("Toy", "a toy (the head noun finds a bear)"),
    ("ai2thor", "VacuumCleaner"): ("Vacuum", "the same machine (the head noun finds shampoo)"),
    ("ai2thor", "DogBed"): (None, "no pets' beds in Stanford's scenes (the head noun finds a bed)"),
    ("ai2thor", "HousePlant"): ("PottedPlant", "a plant in a pot, as Stanford names it 60 times ('Plant': 5)"),
    ("ai2thor", "SideTable"): ("EndTable", "a small table beside a bed or a sofa (the head noun finds 'Table': 6)"),
    ("ai2thor", "Drawer"): (None, "Stanford's drawers are part of their furniture (the parent finds a cabinet)"),
    ("ai2thor", "CounterTop"): ("Counter", "a kitchen counter (the parent finds 'Table': 6)"),
    ("ai2thor", "SinkBasin"): ("Sink", "the basin of a sink (the head noun finds 'Basin': 2)"),
    # Stanford asked of an engine trained on AI2-THOR
    ("stanford", "Cadmium"): ("CD", "ShapeNetSem's synset for these compact discs is cadmium's"),
    ("stanford", "CompactDisk"): ("CD", "the same disc"),
    ("stanford", "MediaDiscs"): ("CD", "discs of media"),
    ("stanford", "Videodisk"): ("CD", "a disc of video"),
    ("stanford", "Cabling"): (None, "cables (the taxonomy's parent is a phone)"),
    ("stanford", "Cake"): (None, "no cake in AI2-THOR (the taxonomy's parent is a plate of food)"),
    ("stanford", "Picture"): ("Painting", "AI2-THOR's framed pictures on walls are its paintings"),
    ("stanford", "WallArt"): ("Painting", "AI2-THOR's framed pictures on walls are its paintings"),
    ("stanford", "Glass"): ("Cup", "a drinking glass; AI2-THOR's drinking vessels are cups and mugs"),
    ("stanford", "DresserWithMirror"): ("Dresser", "a dresser first (the head noun finds the mirror)"),
    ("stanford", "Nightstand"): ("SideTable", "AI2-THOR's nightstands are side tables"),
    ("stanford", "EndTable"): ("SideTable", "an end table is a side table"),
    ("stanford", "Counter"): ("CounterTop", "a kitchen counter"),
    ("stanford", "FileFolder"): (None, "no folders in AI2-THOR (the head noun finds a book)"),
    ("stanford", "Lamp"): ("DeskLamp", "a lamp on a table (the narrower rule finds a candle)"),
    ("stanford", "TableLamp"): ("DeskLamp", "a lamp on a table (the head noun finds a candle)"),
    ("stanford", "WallLamp"): (None, "no wall lamps in AI2-THOR (the head noun finds a candle)"),
    ("stanford", "CeilingLamp"): (None, "no ceiling lamps in AI2-THOR (the head noun finds a candle)"),
    ("stanford", "WallClock"): (None, "no wall clocks in AI2-THOR (the head noun finds an alarm clock)"),
    ("stanford", "Framework"): (None, "a lemma of unlabelled models, not a kind of thing"),
    ("stanford", "NobleMetal"): (None, "a lemma of unlabelled models, not a kind of thing"),
    ("stanford", "KitchenAppliance"): (None, "any appliance (the head noun finds a stove burner)"),
    ("stanford", "AuxiliaryStorage"): (None, "a computer's storage (the head noun finds a drawer)"),
    ("stanford", "DrinkingUtensil"): ("Cup", "something to drink from (the head noun finds a fork)"),
    ("stanford", "Food"): (None, "any food (the narrower rule finds an apple)"),
}


@dataclass(frozen=True)
class Match:
    """Where one category of the corpus asked goes: ``category`` in the training corpus (None: unmapped), by the
    rule ``via`` (see the module), ``through`` what (a synset id, a head noun, a parent category; "" for a name)."""

    category: str | None
    via: str
    through: str = ""


@dataclass
class Crosswalk:
    """Every category of ``test`` (with its instance count) mapped into ``train``'s."""

    test: str
    train: str
    matches: dict[str, Match]
    counts: dict[str, int]

    def category(self, name: str) -> str | None:
        """The training corpus's category for ``name`` (the room shell for the room shell; None: unmapped)."""
        if name == ROOM:
            return ROOM
        match = self.matches.get(name)
        return match.category if match else None

    @property
    def unmapped(self) -> set[str]:
        return {c for c, m in self.matches.items() if m.category is None}

    def relabel(self, scene: Scene) -> Scene:
        """``scene`` with every object's category in the training corpus's vocabulary; an unmapped one keeps its
        own name (and a placeholder stays a placeholder)."""
        objects = {}
        for key, o in scene.objects.items():
            mapped = self.category(o.category)
            objects[key] = replace(o, category=mapped) if mapped is not None else o
        return replace(scene, objects=objects)

    def to_dict(self) -> dict:
        """The mapping as JSON: per category its target, rule and instance count, and the totals."""
        rows = {c: {"category": m.category, "via": m.via, "through": m.through, "instances": self.counts.get(c, 0)}
                for c, m in sorted(self.matches.items(), key=lambda kv: (-self.counts.get(kv[0], 0), kv[0]))}
        unmapped = self.unmapped
        return {"test": self.test, "train": self.train, "categories": len(rows),
                "mapped_categories": len(rows) - len(unmapped), "unmapped_categories": len(unmapped),
                "instances": sum(self.counts.values()),
                "unmapped_instances": sum(self.counts.get(c, 0) for c in unmapped),
                "by_rule": dict(Counter(m.via for m in self.matches.values())), "mapping": rows}


def normalised(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def words(name: str) -> list[str]:
    """The words of a category name: ``GarbageCan`` → garbage, can; ``TVStand`` → tv, stand; ``4Shelves`` →
    shelves."""
    return [w.lower() for w in re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+", name)]


def _kind(corpus: Corpus) -> str:
    return corpus.source.partition(":")[0]


class _Concepts:
    """The WordNet synsets of each category of a corpus (see rule 2 of the module)."""

    def __init__(self, corpus: Corpus, wn: WordNet):
        self.wn = wn
        votes: dict[str, Counter] = {}
        for m in corpus.models.values():
            if m.synset:
                try:
                    sid = synset_id(m.synset)
                    wn.synset(sid)
                except SceneSuggestError:  # a label WordNet does not hold: the name still speaks
                    continue
                votes.setdefault(m.category, Counter())[sid] += 1
        self.taxonomy = corpus.taxonomy
        self.counts = Counter(o.category for s in corpus.scenes for o in s)
        self.of: dict[str, list[str]] = {}
        for c in self.counts:
            found = [votes[c].most_common(1)[0][0]] if c in votes else []
            found += [s for s in self.named(c) if s not in found]
            self.of[c] = found

    def named(self, name: str) -> list[str]:
        """The most frequent sense of ``name`` (its words joined, or run together) that is a physical thing."""
        parts = words(name)
        for lemma in ("_".join(parts), "".join(parts)):
            for sid in self.wn.senses(lemma):
                if self.wn.is_thing(sid):
                    return [sid]
        return []


def _most(candidates: set[str], counts: Counter) -> str:
    return max(sorted(candidates), key=lambda c: counts[c])


def _by_rules(name: str, synsets: list[str], train: _Concepts, wn: WordNet, strict: bool = False) -> Match | None:
    """Rules 1–3 and 5 for a category called ``name`` with ``synsets`` (``strict``: 1–2 only)."""
    by_name = {c for c in train.counts if normalised(c) == normalised(name) and suggestable(c)}
    if by_name:
        return Match(_most(by_name, train.counts), "name")
    holders: dict[str, set[str]] = {}
    for c, sids in train.of.items():
        if suggestable(c) and c != ROOM:
            for sid in sids:
                holders.setdefault(sid, set()).add(c)
    for sid in synsets:
        if sid in holders:
            return Match(_most(holders[sid], train.counts), "synset", sid)
    if strict:
        return None
    best: tuple[int, str] | None = None
    for sid in synsets:
        for up, distance in wn.ancestors(sid):
            if distance > MAX_HYPERNYM_DISTANCE:
                break
            if up in holders and wn.depth(up) >= MIN_DEPTH and (best is None or distance < best[0]):
                best = (distance, up)
    if best is not None:
        return Match(_most(holders[best[1]], train.counts), "hypernym", best[1])
    narrower = {c for sid, cs in holders.items() if set(wn.synset(sid).hypernyms) & set(synsets) for c in cs}
    narrower |= {c for c in train.counts if suggestable(c) and
                 any(normalised(a) == normalised(name) for a in train.taxonomy.ancestors(c))}
    if narrower:
        return Match(_most(narrower, train.counts), "narrower")
    return None


def crosswalk(test: Corpus, train: Corpus, wn: WordNet) -> Crosswalk:
    """Map every category of ``test`` into ``train``'s (see the module)."""
    mine, theirs = _Concepts(test, wn), _Concepts(train, wn)
    kind = _kind(test)

    def direct(name: str, synsets: list[str]) -> Match | None:
        found = _by_rules(name, synsets, theirs, wn)
        if found is None and len(words(name)) > 1:
            head = words(name)[-1]
            found = _by_rules(head, mine.named(head), theirs, wn)
            if found is not None:
                found = Match(found.category, "head", head)
        return found

    matches: dict[str, Match] = {}
    for c in sorted(mine.counts):
        if c == ROOM or not suggestable(c):
            continue
        if (kind, c) in DECISIONS:
            target, reason = DECISIONS[(kind, c)]
            matches[c] = Match(target, "decided", reason)
            continue
        found = direct(c, mine.of[c])
        if found is None:
            for parent in test.taxonomy.ancestors(c):
                decided = DECISIONS.get((kind, parent))
                up = Match(decided[0], "decided") if decided else _by_rules(parent, mine.named(parent), theirs, wn,
                                                                            strict=True)
                if up is not None and up.category is not None:
                    found = Match(up.category, "parent", parent)
                    break
        matches[c] = found or Match(None, "unmapped")
    return Crosswalk(test.source, train.source, matches,
                     {c: n for c, n in mine.counts.items() if c in matches})
