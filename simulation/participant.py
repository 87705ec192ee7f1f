"""A simulated participant: walks the whole study (entry link, device check, consent, demographics,
instructions, every trial, exit survey) through its HTTP interface alone, rebuilding each target
(:mod:`.actions`) in simulated time (:mod:`.timing`), and answers the surveys the way its own times suggest.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np
import scipy.stats

from .actions import BotTrial
from .human import Human
from .page import Page
from .transport import LossyTransport
from .walker import Walker

CONDITION_ORDER = ("none", "basic", "full")


@dataclass(frozen=True)
class Behaviours:
    """How often a bot does what real participants do to a server (all off by default).

    ``reload`` and ``second_tab``: per trial, the page is opened again midway (the trial resumes there);
    ``duplicate_arrival``: per participant, the entry link is followed again after the first trial;
    ``resend``: per batch, the events are posted twice (a lost acknowledgement); ``drop_out``: per participant,
    the bot leaves after a random trial and never finishes; ``lossy``: per request, lost on the way or its
    answer lost after the server acted (see :class:`~.transport.LossyTransport`); ``latency_s``: mean extra
    seconds per round trip (a slow network, real waiting)."""

    reload: float = 0.0
    second_tab: float = 0.0
    duplicate_arrival: float = 0.0
    resend: float = 0.0
    drop_out: float = 0.0
    lossy: float = 0.0
    latency_s: float = 0.0

    @classmethod
    def mixed(cls) -> Behaviours:
        return cls(reload=0.1, second_tab=0.05, duplicate_arrival=0.2, resend=0.1, drop_out=0.1, lossy=0.05)


@dataclass
class BotResult:
    pid: str
    code: str | None = None
    dropped_out: bool = False
    reloads: int = 0
    events: int = 0
    trials: int = 0
    missing_objects: int = 0
    condition_seconds: dict[str, list[float]] = field(default_factory=dict)


class Bot:
    """One simulated participant behaving as ``human`` (default :class:`~.human.Human`); ``speed`` scales every
    operator time (1 = the model's average person; drawn log-normal with ``human.skill_sd`` when not given).
    Scenes are harder or easier for everyone alike: the factor of a scene is drawn from ``scene_seed`` and the
    scene's id."""

    def __init__(self, transport, study: str, pid: str, rng: np.random.Generator, speed: float | None = None,
                 behaviours: Behaviours | None = None, symmetry: dict[str, float] | None = None,
                 human: Human | None = None, scene_seed: int = 0, entry: dict | None = None):
        """``entry``: the entry link's parameters as the study's platform sends them (a pilot's, signed, from
        ``study_server.participants.pilots.entry_query``); default ``pid=`` ``pid``, a link study's."""
        self.http, self.study, self.pid, self.rng = transport, study, pid, rng
        self.entry = entry if entry is not None else {"pid": pid}
        self.human = human or Human()
        self.scene_seed = scene_seed
        #: model id → symmetry period (deg), shared between bots: a person sees that a vase needs no turning
        self.symmetry = symmetry if symmetry is not None else {}
        self.library: dict[str, dict] = {}
        self.fixed: list[dict] = []
        z_speed, u_overlook, u_pad = rng.normal(), rng.random(), rng.random()  # drawn always: common random numbers
        self.speed = speed if speed is not None else float(np.exp(self.human.skill_sd * z_speed))
        #: how much longer this person's drags take than with a mouse (a trackpad's, or 1)
        self.drag_factor = self.human.trackpad_slowdown if u_pad < self.human.trackpad_share else 1.0
        self.does = behaviours or Behaviours()
        if self.does.lossy or self.does.latency_s:
            self.http = LossyTransport(transport, rng, self.does.lossy, self.does.latency_s)
        self.walker = Walker(self.http, study)
        # how often this person overlooks the wanted model in a list (Beta, mean human.overlook, strength 10)
        mean = self.human.overlook
        self.overlook = float(scipy.stats.beta.ppf(u_overlook, 10 * mean, 10 * (1 - mean))) if mean > 0 else 0.0
        self.played = 0  # trials played so far, practice included (the practice effect)
        self.seq = 0
        self.result = BotResult(pid)

    def scene_factor(self, scene: str) -> float:
        """How much harder than average ``scene`` is (a time factor, log-normal with ``human.scene_sd``)."""
        z = np.random.default_rng([self.scene_seed, zlib.crc32(scene.encode())]).normal()
        return float(np.exp(self.human.scene_sd * z))

    def overlooks(self) -> bool:
        return self.rng.random() < self.overlook

    def chance(self, rate: float) -> bool:
        """A behaviour happens (no random draw at all when it is off, so plain runs stay reproducible)."""
        return bool(rate) and self.rng.random() < rate

    def run(self) -> BotResult:
        page = self.walker.enter(self.entry)
        leave_after = int(self.rng.integers(1, 9)) if self.chance(self.does.drop_out) else None
        arrive_again = self.chance(self.does.duplicate_arrival)

        def trial(boot: dict) -> bool:
            nonlocal arrive_again
            self.do_trial(boot)
            if arrive_again and self.result.trials == 1:
                arrive_again = False
                self.walker.enter(self.entry)
            if leave_after is not None and self.result.trials >= leave_after:
                self.result.dropped_out = True
                return False
            return True

        end = self.walker.walk(self.answer, trial, page=page)
        self.result.code = end.code if end.step == "done" else None
        return self.result

    def do_trial(self, boot: dict) -> None:
        seconds = BotTrial(self, boot).play()
        self.played += 1
        if boot["trial"]["kind"] == "trial":
            self.result.trials += 1
            self.result.condition_seconds.setdefault(boot["trial"]["condition"], []).append(seconds)

    def answer(self, page: Page) -> dict:
        """The survey answers of this person: suggestions rated higher, and preferred, when they were faster."""
        times = {c: float(np.mean(v)) for c, v in self.result.condition_seconds.items()}
        fastest = min(times, key=times.get) if times else None
        answers = {}
        for q, values in page.radios.items():
            if q == "preference" and fastest in CONDITION_ORDER and CONDITION_ORDER.index(fastest) < len(values):
                answers[q] = values[CONDITION_ORDER.index(fastest)]
            elif all(v.isdigit() for v in values):
                lift = 1 if ("suggest" in q) == (fastest in ("basic", "full")) else -1
                mid = (len(values) + 1) / 2 + lift * 0.8 + self.rng.normal(0, 0.7)
                answers[q] = str(int(np.clip(round(mid), 1, len(values))))
            else:
                answers[q] = values[int(self.rng.integers(len(values)))]
        for q, (low, high) in page.numbers.items():
            answers[q] = str(int(self.rng.integers(int(max(low, 18)), int(min(high, 70)) + 1)))
        for q in page.texts:
            answers[q] = ""
        if page.step == "exit":
            answers |= {"last_seq": str(self.seq - 1), "attempt": "0"}
        return answers
