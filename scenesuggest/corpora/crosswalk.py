"""Categories mapped from one corpus into another's, so that an engine trained on one can be asked on the other.

Each category of the corpus asked (``test``) is given the category of the training corpus (``train``) that names
the same kind of thing, by the first rule that finds one (its ``via``):

1. ``name`` — the same name, ignoring case and anything but letters and digits (Stanford ``TV`` and a ``Tv``);
2. ``synset`` — the same WordNet 3.0 noun synset. A category's synsets are the majority synset of its models where
   its corpus names them by WordNet lemmas (Stanford's: ShapeNetSem's ``wnlemmas``, kept as a model's
   ``description``; the synset is the sense of the first lemma that holds them all — ShapeNetSem's own ``wnsynset``
   counts in WordNet 3.1) and the most frequent sense of its name that is a physical thing (``GarbageCan`` →
   garbage_can.n.01, whose lemmas Stanford's ``TrashBin`` models carry);
3. ``hypernym`` — a training category whose synset is a hypernym of one of the category's, at most
   :data:`MAX_HYPERNYM_DISTANCE` links up, the nearest first (``ArmChair`` → chair.n.01 → ``Chair``);
4. ``narrower`` — the most common training category one WordNet link or one taxonomy link below the category
   (AI2-THOR's ``Bed`` → Stanford's ``SingleBed``, filed under ``Bed``);
5. ``head`` — rules 1–4 on the last word of a compound name (``SideTable`` → table);
6. ``parent`` — the category's taxonomy parents in its own corpus, nearest first, by a decision or rules 1–2 only
   (Stanford's ``Barstool`` → ``Stool``; a looser match of a parent as broad as "sports equipment" finds shoes).

Where a rule finds several training categories, the one with the most instances is taken. What no rule maps is
*unmapped*: its queries are counted and left out of the figures, and its objects are named ``unmapped:`` and their
own name, which the trained engine has never seen (a parent it knows nothing of; or ``Unknown``, where the
relabelled scenes are trained on). :data:`DECISIONS` overrides the rules where they go wrong, for one pair of
corpora, each with its reason (a decided parent stops the walk up the taxonomy); the room shell is always the room
shell and a placeholder is never mapped.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, replace

from ..library.search import split_camel
from ..scenes.scene import PLACEHOLDERS, ROOM, UNKNOWN, Scene
from .corpus import Corpus
from .wordnet import WordNet

#: Hypernym links a ``hypernym`` match may climb (2: armchair → chair; more reaches "seat", "furniture").
MAX_HYPERNYM_DISTANCE = 2
#: A ``hypernym`` match must name something at least this many links below WordNet's root (chair: 9; box: 7;
#: "instrumentality" or "container": 5 and 6).
MIN_DEPTH = 7
#: Corpora by the kind of their source (``stanford:DIR`` → stanford).
STANFORD, AI2THOR = "stanford", "ai2thor"
#: What an unmapped object is called once relabelled (before its own name).
UNMAPPED = "unmapped:"
#: (the asked corpus's kind, the training corpus's kind) → {category: (the training category, None: unmapped; why)}
#: where the rules are wrong.
DECISIONS: dict[tuple[str, str], dict[str, tuple[str | None, str]]] = {(AI2THOR, STANFORD): {
    "Window": (None, "Stanford's rooms have no windows (the hypernym finds 'Framework', a lemma)"),
    "CD": ("CompactDisk", "WordNet's first physical 'cd' is cadmium"),
    "CreditCard": (None, "no cards in Stanford's scenes (the head noun finds 'Paper')"),
    "KeyChain": ("Key", "a ring of keys (the head noun finds a chain)"),
    "HandTowelHolder": (None, "Stanford's 'Holder' holds pens"),
    "TowelHolder": (None, "Stanford's 'Holder' holds pens"),
    "ToiletPaperHanger": (None, "Stanford's 'Hanger' is a coat hanger"),
    "ShowerHead": (None, "Stanford's 'Head' is a human head"),
    "ShowerGlass": (None, "a shower's glass wall (the head noun finds a drinking glass)"),
    "LaundryHamper": ("Basket", "a hamper is a basket (WordNet's first 'hamper' is a fetter)"),
    "BathtubBasin": ("Bathtub", "the basin of a bathtub (the head noun finds a washbasin)"),
    "Newspaper": ("Magazine", "printed pages folded on a table (the parent finds blank paper)"),
    "Egg": ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    "Lettuce": ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    "Potato": ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    "Tomato": ("FoodItem", "Stanford's food is 'FoodItem' (the parent finds 'Food', one instance)"),
    "DishSponge": (None, "no sponges in Stanford's scenes (the parent finds 'Utensils')"),
    "SaltShaker": ("PepperMill", "a seasoning dispenser (the parent finds 'Utensils')"),
    "PepperShaker": ("PepperMill", "a seasoning dispenser (the parent finds 'Utensils')"),
    "PaperTowelRoll": ("PaperTowel", "the same roll (the parent finds 'Utensils')"),
    "AluminumFoil": (None, "no foil in Stanford's scenes (the parent finds 'Utensils')"),
    "ShelvingUnit": ("4Shelves", "a stand of shelves (the head noun finds a chain)"),
    "CoffeeMachine": ("CoffeeMaker", "the same machine (the head noun finds a stapler)"),
    "WateringCan": (None, "no watering cans in Stanford's scenes (the head noun finds a soda can)"),
    "TeddyBear": ("Toy", "a toy (the head noun finds a bear)"),
    "VacuumCleaner": ("Vacuum", "the same machine (the head noun finds shampoo)"),
    "DogBed": (None, "no pets' beds in Stanford's scenes (the head noun finds a bed)"),
    "HousePlant": ("PottedPlant", "a plant in a pot, as Stanford names it 60 times ('Plant': 5)"),
    "SideTable": ("EndTable", "a small table beside a bed or a sofa (the head noun finds 'Table': 6)"),
    "Drawer": (None, "Stanford's drawers are part of their furniture (the parent finds a cabinet)"),
    "CounterTop": ("Counter", "a kitchen counter (the parent finds 'Table': 6)"),
    "SinkBasin": ("Sink", "the basin of a sink (the head noun finds 'Basin': 2)"),
}, (STANFORD, AI2THOR): {
    "Cadmium": ("CD", "ShapeNetSem's synset for these compact discs is cadmium's"),
    "CompactDisk": ("CD", "the same disc"),
    "MediaDiscs": ("CD", "discs of media"),
    "Videodisk": ("CD", "a disc of video"),
    "Cabling": (None, "cables (the taxonomy's parent is a phone)"),
    "Cake": (None, "no cake in AI2-THOR (the taxonomy's parent is a plate of food)"),
    "Picture": ("Painting", "AI2-THOR's framed pictures on walls are its paintings"),
    "WallArt": ("Painting", "AI2-THOR's framed pictures on walls are its paintings"),
    "Glass": ("Cup", "a drinking glass; AI2-THOR's drinking vessels are cups and mugs"),
    "DresserWithMirror": ("Dresser", "a dresser first (the head noun finds the mirror)"),
    "Nightstand": ("SideTable", "AI2-THOR's nightstands are side tables"),
    "EndTable": ("SideTable", "an end table is a side table"),
    "Counter": ("CounterTop", "a kitchen counter"),
    "FileFolder": (None, "no folders in AI2-THOR (the head noun finds a book)"),
    "Lamp": ("DeskLamp", "a lamp on a table (the narrower rule finds a candle)"),
    "TableLamp": ("DeskLamp", "a lamp on a table (the head noun finds a candle)"),
    "WallLamp": (None, "no wall lamps in AI2-THOR (the head noun finds a candle)"),
    "CeilingLamp": (None, "no ceiling lamps in AI2-THOR (the head noun finds a candle)"),
    "WallClock": (None, "no wall clocks in AI2-THOR (the head noun finds an alarm clock)"),
    "Framework": (None, "a lemma of unlabelled models, not a kind of thing"),
    "NobleMetal": (None, "a lemma of unlabelled models, not a kind of thing"),
    "KitchenAppliance": (None, "any appliance (the head noun finds a stove burner)"),
    "AuxiliaryStorage": (None, "a computer's storage (the head noun finds a drawer)"),
    "DrinkingUtensil": ("Cup", "something to drink from (the head noun finds a fork)"),
    "Food": (None, "any food (the narrower rule finds an apple)"),
    "ToyFigure": (None, "action figures on desks; AI2-THOR's one toy is a teddy bear"),
    "Airplane": (None, "a model plane; AI2-THOR's one toy is a teddy bear"),
    "SpaceShip": (None, "a model ship; AI2-THOR's one toy is a teddy bear"),
    "Car": (None, "a model car; AI2-THOR's one toy is a teddy bear"),
    "Elephant": (None, "a figure of an animal; AI2-THOR's one toy is a teddy bear"),
    "Horse": (None, "a figure of an animal; AI2-THOR's one toy is a teddy bear"),
    "Ipod": ("CellPhone", "a handheld device (its models' lemmas find an apple)"),
    "DecorativeAccessory": (None, "any ornament (its models' lemmas find a plate)"),
    "Board": (None, "a board (its models' lemmas find a dining table)"),
    "CoatRack": (None, "no coat racks in AI2-THOR (the parent finds a shelf)"),
    "CoffeeMaker": ("CoffeeMachine", "the same machine (as the other way round)"),
    "PepperMill": ("PepperShaker", "a seasoning dispenser (as the other way round)"),
    "Magazine": ("Newspaper", "printed pages folded on a table (as the other way round)"),
    "Key": ("KeyChain", "keys on a ring (as the other way round)"),
    "PaperTowel": ("PaperTowelRoll", "the same roll (the head noun finds a cloth towel)"),
}}


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

    def relabel(self, scene: Scene, unmapped_unknown: bool = False) -> Scene:
        """``scene`` with every object's category in the training corpus's vocabulary; an unmapped one is named
        ``unmapped:`` and its own name, which no training corpus has — or, ``unmapped_unknown``, ``Unknown``: a
        placeholder, never suggested nor asked for (a placeholder stays a placeholder)."""
        objects = {}
        for key, o in scene.objects.items():
            if o.category in PLACEHOLDERS - {ROOM}:
                objects[key] = o
                continue
            mapped = self.category(o.category)
            if mapped is None:
                mapped = UNKNOWN if unmapped_unknown else UNMAPPED + o.category
            objects[key] = replace(o, category=mapped)
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
    return [w.lower() for w in re.findall(r"[a-z]+", split_camel(name), flags=re.IGNORECASE)]


def _kind(corpus: Corpus) -> str:
    return corpus.source.partition(":")[0]


class _Concepts:
    """The WordNet synsets of each category of a corpus (see rule 2 of the module)."""

    def __init__(self, corpus: Corpus, wn: WordNet):
        self.wn = wn
        votes: dict[str, Counter] = {}
        if _kind(corpus) == STANFORD:  # a model's description lists its WordNet lemmas (ShapeNetSem's wnlemmas)
            for m in corpus.models.values():
                sid = self.lemmas_sense([w.strip() for w in m.description.split(",") if w.strip()])
                if sid is not None:
                    votes.setdefault(m.category, Counter())[sid] += 1
        self.taxonomy = corpus.taxonomy
        self.counts = Counter(o.category for s in corpus.scenes for o in s)
        self.of: dict[str, list[str]] = {}
        for c in self.counts:
            found = [votes[c].most_common(1)[0][0]] if c in votes else []
            found += [s for s in self.named(c) if s not in found]
            self.of[c] = found
        # what rules 1 and 2 look up, once: the categories by their normalised name and by each of their synsets
        self.by_name: dict[str, set[str]] = {}
        self.holders: dict[str, set[str]] = {}
        for c, sids in self.of.items():
            if c not in PLACEHOLDERS:
                self.by_name.setdefault(normalised(c), set()).add(c)
                for sid in sids:
                    self.holders.setdefault(sid, set()).add(c)

    def lemmas_sense(self, lemmas: list[str]) -> str | None:
        """The sense of the first of ``lemmas`` whose synset holds them all (None: there is none)."""
        wanted = {"_".join(w.lower().split()) for w in lemmas}
        for sid in self.wn.senses(lemmas[0]) if lemmas else ():
            if wanted <= set(self.wn.synset(sid).lemmas):
                return sid
        return None

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
    """Rules 1–4 for a category called ``name`` with ``synsets`` (``strict``: 1–2 only)."""
    by_name = train.by_name.get(normalised(name))
    if by_name:
        return Match(_most(by_name, train.counts), "name")
    holders = train.holders
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
    narrower |= {c for c in train.counts if c not in PLACEHOLDERS and
                 normalised(train.taxonomy.parent(c) or "") == normalised(name)}
    if narrower:
        return Match(_most(narrower, train.counts), "narrower")
    return None


def crosswalk(test: Corpus, train: Corpus, wn: WordNet) -> Crosswalk:
    """Map every category of ``test`` into ``train``'s (see the module)."""
    mine, theirs = _Concepts(test, wn), _Concepts(train, wn)
    pair = (_kind(test), _kind(train))
    decided = {name: (target, why) if target is None or target in theirs.counts else
               (None, f"{why}; but the training scenes have no {target}")
               for name, (target, why) in DECISIONS.get(pair, {}).items()}

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
        if c in PLACEHOLDERS:
            continue
        if c in decided:
            target, reason = decided[c]
            matches[c] = Match(target, "decided", reason)
            continue
        found = direct(c, mine.of[c])
        if found is None:
            for parent in test.taxonomy.ancestors(c):
                if parent in decided:  # decided: mapped or not, the walk ends here
                    target = decided[parent][0]
                    found = Match(target, "parent", parent) if target is not None else None
                    break
                up = _by_rules(parent, mine.of.get(parent) or mine.named(parent), theirs, wn, strict=True)
                if up is not None:
                    found = Match(up.category, "parent", parent)
                    break
        matches[c] = found or Match(None, "unmapped")
    return Crosswalk(test.source, train.source, matches,
                     {c: n for c, n in mine.counts.items() if c in matches})
