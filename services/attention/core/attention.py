"""Whom to look at: the person of interest, chosen by a command, and what to do when they go.

Four requests: look at track ``k``, look at the nearest person, lock onto the nearest person
(take the nearest now, then follow that ID as if asked for it), look at no one. The
chooser keeps its target while it is tracked; when it is gone the head holds still for
``hold_s`` (the tracker often gets a person back within a moment, with the same ID), then
returns to its rest pose. Holding means looking at the place the person was last seen
(so a moving base does not sweep the gaze away). In 'nearest' mode the nearest confirmed person is taken when
there is none to follow (at the start and after the hold), and another person replaces
the one followed only when nearer by ``switch_margin_m``, so two people at about the same
distance do not make the head swing between them, and a confirmed person within
``reacquire_radius_m`` of where the followed one was last seen is taken as them (the
tracker gave them a new ID). 'lock' is for keeping one chosen person in view: 'nearest' hands
the head to whoever is nearest once the person followed is lost, 'lock' waits for that ID
to come back (the tracker's ID memory gives it back to a person it recognises).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = ["Chooser", "Decision", "Person", "Phase", "Request"]

Phase = Literal["track", "hold", "rest"]
Request = Literal["none", "nearest", "id", "lock"]


@dataclass(frozen=True)
class Person:
    """One tracked person: ``position`` and ``velocity`` (3,) in the tracking frame."""

    id: int
    position: np.ndarray
    velocity: np.ndarray
    confirmed: bool = True


@dataclass(frozen=True)
class Decision:
    phase: Phase
    target: Person | None = None  # the person to servo on (track), or where the lost one was last seen (hold)
    target_id: int = -1  # the person followed or waited for (track, hold)


class Chooser:
    """The person-of-interest state machine; ``now`` is in seconds on any monotonic clock."""

    def __init__(self, hold_s: float = 2.0, switch_margin_m: float = 1.5, reacquire_radius_m: float = 0.8) -> None:
        self.hold_s = hold_s
        self.switch_margin_m = switch_margin_m
        self.reacquire_radius_m = reacquire_radius_m
        self._last_seen: Person | None = None
        self._others: set[int] = set()  # the IDs tracked beside the one followed, when last seen
        self.mode: Request = "none"
        self.requested_id = -1
        self.following_id = -1  # the person followed now (track or hold), -1 for none
        self._lost_at: float | None = None

    def request(self, mode: Request, track_id: int = -1) -> None:
        """Look at ``track_id`` (mode 'id'), at the nearest person, lock onto the nearest
        person ('lock': the mode becomes 'id' with their ID once there is one), or at no one."""
        self.mode = mode
        self.requested_id = track_id if mode == "id" else -1
        self.following_id = track_id if mode == "id" else -1
        self._lost_at = None
        self._last_seen = None

    def _nearest(self, people: list[Person], origin: np.ndarray) -> Person | None:
        confirmed = [p for p in people if p.confirmed]
        if not confirmed:
            return None
        return min(confirmed, key=lambda p: float(np.linalg.norm(p.position[:2] - origin[:2])))

    def _reacquire(self, people: list[Person]) -> Person | None:
        """'nearest': a new confirmed person (not one tracked beside the followed one) where the
        one followed was last seen (the tracker gave them a new ID), or None."""
        assert self._last_seen is not None
        near = [p for p in people if p.confirmed and p.id not in self._others and float(np.linalg.norm(
            p.position[:2] - self._last_seen.position[:2])) <= self.reacquire_radius_m]
        return min(near, key=lambda p: float(np.linalg.norm(p.position[:2] - self._last_seen.position[:2]))) \
            if near else None  # type: ignore[union-attr]

    def decide(self, people: list[Person], origin: np.ndarray, now: float) -> Decision:
        """What to do with the people tracked now; ``origin`` (3,): the camera's position."""
        if self.mode == "none":
            return Decision("rest")
        if self.mode == "lock":
            chosen = self._nearest(people, origin)
            if chosen is None:
                return Decision("rest")
            self.request("id", chosen.id)
        by_id = {p.id: p for p in people}
        current = by_id.get(self.following_id)
        if self.mode == "nearest" and current is not None:
            nearest = self._nearest(people, origin)
            if nearest is not None and nearest.id != current.id:
                d_near = float(np.linalg.norm(nearest.position[:2] - origin[:2]))
                d_cur = float(np.linalg.norm(current.position[:2] - origin[:2]))
                if d_near + self.switch_margin_m < d_cur:
                    current = nearest
                    self.following_id = nearest.id
        if current is None and self.mode == "nearest" and self._last_seen is not None:
            current = self._reacquire(people)
        if current is not None:
            self._lost_at = None
            self._last_seen = current
            self._others = {p.id for p in people if p.id != current.id}
            self.following_id = current.id
            return Decision("track", current, current.id)
        if self.following_id >= 0:  # the person followed is gone: hold, then give up on them
            if self._lost_at is None:
                self._lost_at = now
            if now - self._lost_at < self.hold_s:
                last = self._last_seen
                still = None if last is None else Person(last.id, last.position, np.zeros(3), last.confirmed)
                return Decision("hold", still, self.following_id)
            if self.mode == "nearest":
                self.following_id = -1
        if self.mode == "nearest":
            nearest = self._nearest(people, origin)
            if nearest is not None:
                self.following_id = nearest.id
                self._lost_at = None
                self._last_seen = nearest
                return Decision("track", nearest, nearest.id)
        return Decision("rest")
