"""Identity per person: which people each track ID covered, and what ID a person got on returning.

A tracker's ID memory gives a returning person their old ID; it can also hand a
remembered ID to someone else, a newcomer included, which ID switches do not count (a
person's *first* match is never a switch). This core takes the evaluation's per-frame
matched pairs (GT ID, track ID) and the ground truth's presence, and nothing else
(numpy and dataclasses only).

Definitions (``gap`` and ``min_frames`` are the arguments of :func:`identity_measures`):

- **Appearance.** A person's GT frames split wherever ``gap`` or more frame numbers in a
  row lack them: the first appearance, then one *return* per such gap.
- **The ID given** in an appearance is the track ID of the person's first match in it.
  An appearance never matched gives none (``unmatched``).
- **A return** is a *true recovery* when that ID had been matched to this person before
  the appearance, a *false recovery* when it had instead been matched, in an earlier
  frame, to another person, and a *missed recovery* otherwise (an ID new to the matching).
- **A first appearance** whose ID had been matched, in an earlier frame, to another person
  is a *false recovery* of a newcomer (a stranger given a departed person's ID).
- **Shared track IDs**: track IDs matched to two or more people for at least
  ``min_frames`` frames each (shorter contacts are blips, not counted).

Only matched pairs count as use of an ID: a track that was only ever a false positive
leaves no trace here.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, fields, replace
from typing import Iterable

import numpy as np
from numpy.typing import ArrayLike

from tools.evaluation.metrics import FrameEvents

__all__ = ["DEFAULT_GAP", "DEFAULT_MIN_FRAMES", "Appearance", "Identity", "IdentityCollector", "identity_measures"]

#: Frames out of the ground truth after which a person's next appearance is a return.
DEFAULT_GAP = 10
#: Matched frames a person needs in a track ID for the ID to count as covering them.
DEFAULT_MIN_FRAMES = 5

#: Outcomes of an appearance.
TRUE, MISSED, FALSE, NEW, UNMATCHED = "true recovery", "missed recovery", "false recovery", "new", "unmatched"


@dataclass(frozen=True)
class Appearance:
    """One appearance of a person: its first GT frame, the frame and track ID of its first match.

    ``outcome``: for a return, ``true recovery``, ``missed recovery``, ``false recovery`` or
    ``unmatched``; for a first appearance, ``new`` or ``false recovery`` (or ``unmatched``).
    ``owners``: the other people the given ID had been matched to before (false recoveries).
    """

    person: int
    start: int
    returning: bool
    outcome: str
    frame: int | None = None
    track: int | None = None
    previous: tuple[int, ...] = ()  # this person's track IDs before this appearance
    owners: tuple[int, ...] = ()
    #: the last frame before ``frame`` in which another person was first matched with ``track``
    #: (None: nobody else had it): a decision about the ID before then was about them
    taken: int | None = None

    def to_dict(self) -> dict[str, object]:
        return {"person": self.person, "start": self.start, "returning": self.returning, "outcome": self.outcome,
                "frame": self.frame, "track": self.track, "previous": list(self.previous),
                "owners": list(self.owners), "taken": self.taken}


@dataclass(frozen=True)
class Identity:
    """The identity measures of one sequence (``coverage`` and ``events``), or totals of several."""

    returns: int = 0
    true_recoveries: int = 0
    missed_recoveries: int = 0
    false_recoveries: int = 0  # returns and newcomers given another person's ID
    false_newcomers: int = 0  # of which newcomers
    unmatched_returns: int = 0
    shared_tracks: int = 0
    coverage: dict[int, dict[int, int]] = field(default_factory=dict)  # track ID -> person -> matched frames
    events: tuple[Appearance, ...] = ()  # every appearance but plain first ones
    gap: int = DEFAULT_GAP
    min_frames: int = DEFAULT_MIN_FRAMES

    _COUNTS = ("returns", "true_recoveries", "missed_recoveries", "false_recoveries", "false_newcomers",
               "unmatched_returns", "shared_tracks")

    @classmethod
    def combine(cls, parts: Iterable[Identity]) -> Identity:
        """Totals over sequences (their IDs unrelated): counts only, no coverage or events."""
        parts = list(parts)
        counts = {name: sum(getattr(p, name) for p in parts) for name in cls._COUNTS}
        gap = parts[0].gap if parts else DEFAULT_GAP
        min_frames = parts[0].min_frames if parts else DEFAULT_MIN_FRAMES
        return cls(**counts, gap=gap, min_frames=min_frames)

    def shared(self) -> dict[int, dict[int, int]]:
        """The track IDs covering two or more people for ``min_frames`` frames each."""
        return {t: people for t, people in self.coverage.items()
                if sum(n >= self.min_frames for n in people.values()) >= 2}

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {f.name: getattr(self, f.name) for f in fields(self)
                                  if f.name not in ("coverage", "events")}
        out["coverage"] = {str(t): {str(p): n for p, n in people.items()} for t, people in self.coverage.items()}
        out["events"] = [e.to_dict() for e in self.events]
        return out


def identity_measures(match_frames: ArrayLike, match_gt: ArrayLike, match_tracks: ArrayLike,
                      gt_frames: ArrayLike, gt_ids: ArrayLike, gap: int = DEFAULT_GAP,
                      min_frames: int = DEFAULT_MIN_FRAMES) -> Identity:
    """The identity measures of one sequence.

    match_frames, match_gt, match_tracks (K,) int: the matched pairs (ID switches included),
    one per (frame, person). gt_frames, gt_ids (G,) int: the ground truth's rows.
    ``gap`` (>= 1): frames out of the ground truth that make the next appearance a return;
    ``min_frames`` (>= 1): matched frames for a person to count in a shared track ID.
    """
    if gap < 1 or min_frames < 1:
        raise ValueError(f"gap and min_frames must be >= 1, got {gap} and {min_frames}")
    mf, mg, mt = (np.asarray(a, dtype=np.int64).reshape(-1) for a in (match_frames, match_gt, match_tracks))
    gf, gi = (np.asarray(a, dtype=np.int64).reshape(-1) for a in (gt_frames, gt_ids))
    if not mf.size == mg.size == mt.size or gf.size != gi.size:
        raise ValueError("match arrays, and GT arrays, must have equal lengths")
    order = np.lexsort((mg, mf))
    mf, mg, mt = mf[order], mg[order], mt[order]

    coverage: dict[int, Counter[int]] = {}
    for t, g in zip(mt.tolist(), mg.tolist()):
        coverage.setdefault(t, Counter())[g] += 1

    # first frame each (track, person) pair was matched: "had been matched before"
    first_pair: dict[tuple[int, int], int] = {}
    for f, g, t in zip(mf.tolist(), mg.tolist(), mt.tolist()):
        first_pair.setdefault((t, g), f)
    users: dict[int, list[tuple[int, int]]] = {}  # track -> [(first frame, person)]
    for (t, g), f in first_pair.items():
        users.setdefault(t, []).append((f, g))

    events: list[Appearance] = []
    counts: Counter[str] = Counter()
    for person in np.unique(gi).tolist():
        frames = np.unique(gf[gi == person])
        starts = np.concatenate(([0], np.flatnonzero(np.diff(frames) > gap) + 1))
        mine = mg == person
        pf, pt = mf[mine], mt[mine]
        for k, s in enumerate(starts.tolist()):
            start = int(frames[s])
            end = int(frames[starts[k + 1] - 1]) if k + 1 < len(starts) else int(frames[-1])
            returning = k > 0
            previous = tuple(sorted(set(pt[pf < start].tolist())))
            inside = np.flatnonzero((pf >= start) & (pf <= end))
            if inside.size == 0:
                if returning:
                    counts["unmatched"] += 1
                    counts["returns"] += 1
                    events.append(Appearance(person, start, True, UNMATCHED, previous=previous))
                continue
            frame, track = int(pf[inside[0]]), int(pt[inside[0]])
            others = [(f, g) for f, g in users.get(track, []) if g != person and f <= frame]
            owners = tuple(sorted(g for f, g in others if f < frame))
            taken = max((f for f, _ in others), default=None)
            if returning and track in previous:
                outcome = TRUE
            elif owners:
                outcome = FALSE
            else:
                outcome = MISSED if returning else NEW
            counts["returns"] += returning
            counts[outcome] += 1
            counts["false_new"] += outcome == FALSE and not returning
            if returning or outcome == FALSE:
                events.append(Appearance(person, start, returning, outcome, frame, track, previous, owners, taken))

    result = Identity(
        returns=counts["returns"], true_recoveries=counts[TRUE], missed_recoveries=counts[MISSED],
        false_recoveries=counts[FALSE], false_newcomers=counts["false_new"], unmatched_returns=counts["unmatched"],
        coverage={t: dict(sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))) for t, c in sorted(coverage.items())},
        events=tuple(sorted(events, key=lambda e: (e.frame if e.frame is not None else e.start, e.person))),
        gap=gap, min_frames=min_frames)
    return replace(result, shared_tracks=len(result.shared()))


class IdentityCollector:
    """Collects the matched pairs of an evaluation, frame by frame (an ``on_frame`` callback).

    >>> collect = IdentityCollector()                               # doctest: +SKIP
    >>> evaluate_tables(gt, hyp, on_frame=collect)                  # doctest: +SKIP
    >>> collect.result(gt.frames, gt.ids)                           # doctest: +SKIP
    """

    def __init__(self) -> None:
        self._frames: list[int] = []
        self._gt: list[int] = []
        self._tracks: list[int] = []

    def __call__(self, frame: int, events: FrameEvents) -> None:
        for g, t, _ in (*events.matches, *events.switches):
            self._frames.append(frame)
            self._gt.append(g)
            self._tracks.append(t)

    def result(self, gt_frames: ArrayLike, gt_ids: ArrayLike, gap: int = DEFAULT_GAP,
               min_frames: int = DEFAULT_MIN_FRAMES) -> Identity:
        return identity_measures(self._frames, self._gt, self._tracks, gt_frames, gt_ids, gap, min_frames)
