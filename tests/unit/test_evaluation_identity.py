"""Identity per person (tools/evaluation/identity.py) on hand-made sequences."""

from __future__ import annotations

import numpy as np
import pytest

from tools.evaluation.identity import Identity, identity_measures


def run(tracks: dict[int, dict[int, int]], gt: dict[int, list[int]] | None = None, **kw: int) -> Identity:
    """``tracks``: person -> {frame: track ID} (the matches); ``gt``: person -> frames present
    (default: the matched frames)."""
    rows = [(f, p, t) for p, per in tracks.items() for f, t in per.items()]
    mf, mg, mt = (np.array([r[k] for r in rows], dtype=np.int64) for k in range(3))
    gt = gt or {p: sorted(per) for p, per in tracks.items()}
    gf = np.array([f for p in gt for f in gt[p]], dtype=np.int64)
    gi = np.array([p for p in gt for _ in gt[p]], dtype=np.int64)
    return identity_measures(mf, mg, mt, gf, gi, **kw)


def span(a: int, b: int, track: int) -> dict[int, int]:
    return {f: track for f in range(a, b)}


def test_true_recovery() -> None:
    r = run({1: {**span(0, 20, 7), **span(40, 60, 7)}})
    assert (r.returns, r.true_recoveries, r.missed_recoveries, r.false_recoveries) == (1, 1, 0, 0)
    (e,) = r.events
    assert (e.person, e.start, e.frame, e.track, e.outcome, e.previous) == (1, 40, 40, 7, "true recovery", (7,))


def test_missed_recovery() -> None:
    r = run({1: {**span(0, 20, 7), **span(40, 60, 8)}})
    assert (r.returns, r.true_recoveries, r.missed_recoveries, r.false_recoveries) == (1, 0, 1, 0)
    assert r.coverage == {7: {1: 20}, 8: {1: 20}} and r.shared_tracks == 0


def test_false_recovery_on_return() -> None:
    # person 2 leaves after track 8 followed it; person 1 comes back as 8
    r = run({1: {**span(0, 20, 7), **span(40, 60, 8)}, 2: span(0, 30, 8)})
    assert (r.returns, r.true_recoveries, r.missed_recoveries, r.false_recoveries, r.false_newcomers) == (1, 0, 0, 1, 0)
    (e,) = r.events
    assert (e.person, e.track, e.owners, e.outcome) == (1, 8, (2,), "false recovery")
    assert r.shared_tracks == 1 and r.shared() == {8: {2: 30, 1: 20}}


def test_newcomer_given_a_departed_persons_id() -> None:
    r = run({1: span(0, 20, 7), 2: span(50, 70, 7)})
    assert (r.returns, r.false_recoveries, r.false_newcomers, r.shared_tracks) == (0, 1, 1, 1)
    (e,) = r.events
    assert (e.person, e.returning, e.frame, e.track, e.owners) == (2, False, 50, 7, (1,))


def test_short_gap_is_no_return_and_gap_is_a_setting() -> None:
    tracks = {1: {**span(0, 20, 7), **span(25, 40, 7)}}
    assert run(tracks).returns == 0
    assert run(tracks, gap=4).true_recoveries == 1


def test_first_id_of_the_return_decides_and_unmatched_returns() -> None:
    # back at frame 40, unmatched until 45 (then 9, then its own 7 again): a missed recovery
    r = run({1: {**span(0, 20, 7), **span(45, 50, 9), **span(50, 60, 7)}}, gt={1: [*range(0, 20), *range(40, 60)]})
    assert r.missed_recoveries == 1 and r.events[0].frame == 45
    r = run({1: span(0, 20, 7)}, gt={1: [*range(0, 20), *range(40, 60)]})
    assert (r.returns, r.unmatched_returns, r.true_recoveries) == (1, 1, 0)


def test_blips_do_not_make_a_shared_id() -> None:
    r = run({1: span(0, 30, 7), 2: {**span(10, 13, 7), **span(13, 30, 8)}})
    assert r.coverage[7] == {1: 30, 2: 3} and r.shared_tracks == 0
    assert run({1: span(0, 30, 7), 2: {**span(10, 13, 7), **span(13, 30, 8)}}, min_frames=3).shared_tracks == 1


def test_combine_and_json() -> None:
    a = run({1: {**span(0, 20, 7), **span(40, 60, 7)}})
    b = run({1: span(0, 20, 7), 2: span(50, 70, 7)})
    total = Identity.combine([a, b])
    assert (total.returns, total.true_recoveries, total.false_recoveries, total.false_newcomers) == (1, 1, 1, 1)
    d = b.to_dict()
    assert d["coverage"] == {"7": {"1": 20, "2": 20}} and d["events"][0]["owners"] == [1]


def test_bad_settings() -> None:
    with pytest.raises(ValueError, match="gap"):
        run({1: span(0, 5, 1)}, gap=0)


def test_cli_identity(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """perception evaluate --identity on small CSVs: person 1 leaves, person 2 arrives and gets
    track 7 (person 1's), person 1 comes back as the new track 9."""
    import json

    from perception.cli import main

    gt = ["frame,id,x,y,z"]
    tracks = ["frame,stamp,id,x,y,z"]
    for f in range(0, 20):
        gt.append(f"{f},1,0.0,0.0,0.0")
        tracks.append(f"{f},{f / 10},7,0.1,0.0,0.0")
    for f in range(30, 50):
        gt.append(f"{f},2,5.0,0.0,0.0")
        tracks.append(f"{f},{f / 10},7,5.1,0.0,0.0")
    for f in range(60, 70):
        gt.append(f"{f},1,0.0,0.0,0.0")
        tracks.append(f"{f},{f / 10},9,0.1,0.0,0.0")
    (tmp_path / "gt.csv").write_text("\n".join(gt) + "\n")
    (tmp_path / "tracks.csv").write_text("\n".join(tracks) + "\n")
    argv = ["evaluate", "--gt", str(tmp_path / "gt.csv"), "--tracks", str(tmp_path / "tracks.csv"), "--identity"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "Identity per person" in text and "  7*: 1: 20, 2: 20" in text
    assert all(len(line) <= 80 for line in text[text.index("Identity per person"):].splitlines())
    assert main([*argv, "--json"]) == 0
    ident = json.loads(capsys.readouterr().out)["identity"]
    seq = next(iter(ident["sequences"].values()))
    assert seq["coverage"] == {"7": {"1": 20, "2": 20}, "9": {"1": 10}}
    assert [(e["person"], e["outcome"], e["track"]) for e in seq["events"]] == [
        (2, "false recovery", 7), (1, "missed recovery", 9)]
    assert {k: ident["overall"][k] for k in ("returns", "missed_recoveries", "false_recoveries", "false_newcomers",
                                             "shared_tracks")} == dict(returns=1, missed_recoveries=1,
                                                                        false_recoveries=1, false_newcomers=1,
                                                                        shared_tracks=1)
    assert main([*argv, "--gap", "0"]) == 2
