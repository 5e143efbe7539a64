"""Why each person got their ID (tools/evaluation/why.py): the identity measures joined to the
tracker's ID decisions (perception track --id-log): a decision in the appearance, a track the
association continued, a newcomer with nothing weighed; the file's errors name the line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from perception.cli import main
from services.tracker.core.types import IdCandidate, IdDecision
from tools.evaluation.identity import identity_measures
from tools.evaluation.readers import EvaluationInputError
from tools.evaluation.why import false_by_decision, format_reasons, read_id_log, reasons


def decision(track_id: int, outcome: str = "recovered", stamp: float = 6.0) -> IdDecision:
    cand = IdCandidate(track_id if outcome == "recovered" else 7, 3.2, 0.8 if outcome == "recovered" else 0.3, True,
                       True, 4.0, 0.6)
    return IdDecision(stamp, track_id, outcome, 0.1, 0.0, cand.support, 0.5, 0.1, 0.2, (cand,))  # type: ignore[arg-type]


def scene() -> tuple:  # type: ignore[type-arg]
    """Person 1 on track 7 (frames 0-19), person 2 continues track 7 (30-49), person 1 back as 9 (60-69)."""
    rows = [(f, 1, 7) for f in range(20)] + [(f, 2, 7) for f in range(30, 50)] + [(f, 1, 9) for f in range(60, 70)]
    mf, mg, mt = (np.array([r[k] for r in rows]) for k in range(3))
    return identity_measures(mf, mg, mt, mf, mg)


def test_each_return_and_false_recovery_gets_its_reason() -> None:
    ident = scene()
    decisions = [(3, IdDecision(0.3, 7, "new", 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, ())),  # track 7's ID, long before
                 (60, decision(9, "new"))]  # person 1 back: weighed, and given a new ID
    second, back = reasons(ident, decisions)
    assert (second.event.person, second.event.outcome, second.decision) == (2, "false recovery", None)
    assert "the association continued track 7" in second.text and "frame 3" in second.text
    assert (back.event.person, back.event.outcome, back.frame) == (1, "missed recovery", 60)
    assert back.text == decisions[1][1].summary() and back.text.startswith("new ID 9")
    nothing = reasons(ident, [])
    assert [r.decision for r in nothing] == [None, None] and "nobody remembered to weigh" in nothing[1].text
    text = format_reasons([("seq", [second, back])])
    assert "person 1 from frame 60 (return), missed recovery, ID 9:" in text
    assert all(len(line) <= 80 for line in text.splitlines())
    json.dumps([r.to_dict() for r in (second, back)], allow_nan=False)
    assert false_by_decision([second, back]) == {"memory": 0, "handover": 0, "association": 1}  # person 2's
    given = reasons(ident, [(30, decision(7))])  # had the memory given person 2 track 7's ID at frame 30
    assert given[0].decision is not None and false_by_decision(given)["memory"] == 1


def test_a_decision_round_trips_and_a_bad_line_is_named(tmp_path: Path) -> None:
    d = decision(4)
    path = tmp_path / "ids.jsonl"
    path.write_text(json.dumps({"frame": 12, **d.as_dict()}) + "\n\n" + '{"frame": 13, "id": 5}\n')
    with pytest.raises(EvaluationInputError, match=r"ids.jsonl, line 3: not an ID decision"):
        read_id_log(path)
    path.write_text(json.dumps({"frame": 12, **d.as_dict()}) + "\n")
    assert read_id_log(path) == [(12, d)]


def test_cli_tracks_then_explains(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """perception track --id-log, then perception evaluate --identity --id-log: one person walks,
    is gone for 4 s and comes back; the return is a true recovery, and the reason is the decision."""
    rng = np.random.default_rng(0)
    look = rng.normal(size=8)
    look /= np.linalg.norm(look)
    dets, gt = ["frame,stamp,x,y,z,score" + "".join(f",e{i}" for i in range(8))], ["frame,id,x,y,z"]
    for k in list(range(0, 60)) + list(range(180, 240)):
        x = 1.0 + (0.3 if k >= 180 else 0.0)
        e = look + rng.normal(scale=0.01, size=8)
        dets.append(",".join([str(k), f"{k / 30:.6f}", f"{x:.3f}", "0.0", "1.0", "0.9"]
                             + [f"{v:.5f}" for v in e / np.linalg.norm(e)]))
        gt.append(f"{k},1,{x:.3f},0.0,1.0")
    for name, lines in (("dets.csv", dets), ("gt.csv", gt)):
        (tmp_path / name).write_text("\n".join(lines) + "\n")
    assert main(["track", "--detections", str(tmp_path / "dets.csv"), "--output", str(tmp_path / "tracks.csv"),
                 "--id-log", str(tmp_path / "ids.jsonl")]) == 0
    argv = ["evaluate", "--gt", str(tmp_path / "gt.csv"), "--tracks", str(tmp_path / "tracks.csv"), "--identity",
            "--id-log", str(tmp_path / "ids.jsonl")]
    capsys.readouterr()
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "person 1 from frame 180 (return), true recovery, ID 1:" in text and "ID 1 recovered at" in text
    assert main([*argv, "--json"]) == 0
    [[why]] = json.loads(capsys.readouterr().out)["why"].values()
    assert (why["outcome"], why["decision"]["outcome"], why["decision"]["candidates"][0]["id"]) == (
        "true recovery", "recovered", 1)
    assert main(argv[:-3] + ["--id-log", str(tmp_path / "ids.jsonl")]) == 2  # --id-log needs --identity
    assert "add --identity" in capsys.readouterr().err


def test_a_decision_for_someone_else_just_before_is_not_this_persons() -> None:
    """Track 7 is confirmed for person 3 at frame 40 (a new ID, weighed); person 2, back at frame
    45, is then taken by the association onto track 7: the decision was person 3's."""
    rows = ([(f, 2, 2) for f in range(20)] + [(f, 3, 7) for f in range(40, 44)] + [(f, 2, 7) for f in range(45, 60)])
    mf, mg, mt = (np.array([r[k] for r in rows]) for k in range(3))
    ident = identity_measures(mf, mg, mt, mf, mg)
    [back] = [e for e in ident.events if e.person == 2]
    assert (back.outcome, back.track, back.taken) == ("false recovery", 7, 40)
    [why] = reasons(ident, [(40, decision(7, "new"))])
    assert why.decision is None and "the association continued track 7" in why.text
    assert false_by_decision([why])["association"] == 1


def test_a_directory_of_logs_one_per_sequence(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    from tools.evaluation.why import id_logs

    (tmp_path / "ids_a.jsonl").write_text(json.dumps({"frame": 5, **decision(4).as_dict()}) + "\n")
    (tmp_path / "b.jsonl").write_text("")
    logs = id_logs(tmp_path, ["a", "b", "c"])
    assert logs == {"a": [(5, decision(4))], "b": []} and "no ID decisions for sequence c" in caplog.text
    with pytest.raises(EvaluationInputError, match="one file, for 2 sequences"):
        id_logs(tmp_path / "ids_a.jsonl", ["a", "b"])
    with pytest.raises(EvaluationInputError, match="no such file"):
        id_logs(tmp_path / "missing", ["a"])
