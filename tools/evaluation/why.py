"""Why each person got the ID they got: the identity measures beside the tracker's ID decisions.

``perception evaluate --identity`` says *what* happened to each person who came back (their own
ID, a new one, someone else's) and to newcomers given another's ID; ``perception track --id-log``
(or the tracker service's log) says *why* the robust profile decided each ID. This joins the two:
for each return and each false recovery, the decision that gave the track its ID in that
appearance, or, when there was none, that the track was continued by the association (its ID
decided earlier, for whoever it followed then) or that its ID was new with nobody to weigh.

A decision belongs to an appearance when it gave the appearance's track ID no later than the
first match, no earlier than ``gap`` frames before the person appeared (a track is confirmed a
few frames after the detector first sees someone, who may be seen before the ground truth has
them), and after anyone else was first matched with that ID (a decision before then was theirs).
"""

from __future__ import annotations

import json
import logging
import textwrap
from dataclasses import dataclass
from pathlib import Path

from services.tracker.core.types import IdDecision
from tools.evaluation.identity import FALSE, MISSED, TRUE, Appearance, Identity
from tools.evaluation.readers import EvaluationInputError

__all__ = ["Reason", "false_by_decision", "format_reasons", "id_logs", "read_id_log", "reasons"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Reason:
    """An appearance (``event``) and why its ID: the ``decision`` (its ``frame``) that gave it, or
    ``None`` with ``text`` saying what happened instead."""

    event: Appearance
    text: str
    decision: IdDecision | None = None
    frame: int | None = None

    def to_dict(self) -> dict[str, object]:
        return {"person": self.event.person, "start": self.event.start, "outcome": self.event.outcome,
                "track": self.event.track, "why": self.text, "decision_frame": self.frame,
                "decision": None if self.decision is None else self.decision.as_dict()}


def read_id_log(path: Path) -> list[tuple[int, IdDecision]]:
    """(frame, decision) of each line of ``perception track --id-log``'s file;
    :class:`EvaluationInputError` naming the line of a malformed one."""
    out = []
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise EvaluationInputError(f"{path}: {exc.strerror or exc}") from exc
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            data = json.loads(line)
            frame = data["frame"]
            if not isinstance(frame, int):
                raise ValueError(f"frame {frame!r} is not a frame number")
            out.append((frame, IdDecision.from_dict(data)))
        except (ValueError, KeyError, TypeError) as exc:
            raise EvaluationInputError(f"{path}, line {n}: {exc} (expected perception track --id-log's lines)") from exc
    return out


def id_logs(path: Path, names: list[str]) -> dict[str, list[tuple[int, IdDecision]]]:
    """The decisions of each sequence in ``names``: ``path`` is one file (one sequence), or a
    directory of ``ids_SEQ.jsonl`` or ``SEQ.jsonl`` files (a sequence without one: a warning)."""
    if not path.exists():
        raise EvaluationInputError(f"{path}: no such file or directory")
    if path.is_file():
        if len(names) != 1:
            raise EvaluationInputError(f"{path} is one file, for {len(names)} sequences: give a directory of "
                                       "ids_SEQ.jsonl files")
        return {names[0]: read_id_log(path)}
    out = {}
    for name in names:
        found = [p for p in (path / f"ids_{name}.jsonl", path / f"{name}.jsonl") if p.is_file()]
        if found:
            out[name] = read_id_log(found[0])
        else:
            log.warning("no ID decisions for sequence %s in %s (ids_%s.jsonl)", name, path, name)
    return out


def reasons(identity: Identity, decisions: list[tuple[int, IdDecision]]) -> list[Reason]:
    """Why, for each return and each false recovery of ``identity`` (one sequence)."""
    out = []
    for e in identity.events:
        if e.track is None or e.frame is None or e.outcome not in (TRUE, MISSED, FALSE):
            continue
        given = [(f, d) for f, d in decisions if d.id == e.track and f <= e.frame]
        mine = [(f, d) for f, d in given if f >= e.start - identity.gap and (e.taken is None or f > e.taken)]
        if mine:
            f, d = mine[-1]
            out.append(Reason(e, d.summary(), d, f))
        elif given:
            f, d = given[-1]
            out.append(Reason(e, f"no ID decision: the association continued track {e.track} to this person "
                                 f"(its ID was decided at frame {f}, {d.outcome})"))
        else:
            out.append(Reason(e, f"no ID decision: track {e.track}'s ID was new with nobody remembered to weigh, "
                                 "or the association continued the track to this person"))
    return out


def false_by_decision(found: list[Reason]) -> dict[str, int]:
    """The false recoveries among ``found`` by who made them: ``memory`` (the ID memory's
    decision), ``handover`` (a hand-over between cameras), ``association`` (no decision: the
    association continued a track to another person)."""
    out = {"memory": 0, "handover": 0, "association": 0}
    for r in found:
        if r.event.outcome == FALSE:
            kind = "association" if r.decision is None else "handover" if r.decision.outcome == "handover" else "memory"
            out[kind] += 1
    return out


def format_reasons(per_sequence: list[tuple[str, list[Reason]]], width: int | None = 80) -> str:
    """The reasons as text, per sequence (lines wrapped at ``width``; None: not wrapped)."""
    out = ["Why (the tracker's ID decisions, perception track --id-log):"]
    for name, rs in per_sequence:
        out.append(f"{name}:")
        if not rs:
            out.append("  no returns and no false recoveries")
        for r in rs:
            e = r.event
            head = f"  person {e.person} from frame {e.start} ({'return' if e.returning else 'first'}), " \
                   f"{e.outcome}, ID {e.track}"
            text = r.text if width is None else textwrap.fill(r.text, width, initial_indent="    ",
                                                                 subsequent_indent="      ").lstrip()
            out.append(f"{head}:\n    {text}")
    return "\n".join(out)
