"""The demo's live table and its closing tables: true rates, tracks by state, 80 columns."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.messages.keys import Keys
from common.messages.schemas import Detections, Header, ServiceStatus, Tracks, TrackState
from common.transport.memory import MemoryBus
from tools.demo.monitor import STAGES, Monitor
from tools.demo.scoring import pose_line, score_rows
from tools.demo.text import WIDTH, attention_line, closing_text
from tools.drawing.meters import StageMeter

T0_NS = 1_700_000_000_000_000_000
RATE_HZ = 10.0


def _track(tid: int, status: str, x: float) -> TrackState:
    return TrackState(id=tid, status=status, position=np.array([x, 2.0 - x, 1.1]), velocity=np.array([0.4, -0.3, 0.0]),
                      covariance=np.eye(6), last_update_ns=0, hits=40 + tid, age_s=12.5, posture=[1 / 3] * 3,
                      orientation=[1 / 8] * 8)


def _fed_monitor(seconds: float = 20.0) -> tuple[Monitor, float]:
    """A monitor that saw every stage at 10 Hz for ``seconds`` (receive stamps jittered by a few
    ms, each stage 5-60 ms after the frame), and the wall time (s) of the last arrival."""
    monitor = Monitor(MemoryBus().transport(), Keys(robot="tabletest"))
    rng = np.random.default_rng(0)
    people = [_track(1, "confirmed", 0.5), _track(2, "coasting", 1.5), _track(3, "confirmed", -1.0),
              _track(4, "tentative", 3.0)]
    last = 0.0
    for k in range(int(seconds * RATE_HZ)):
        stamp = T0_NS + int(k * 1e9 / RATE_HZ)
        header = Header(stamp_ns=stamp, seq=k + 1)
        for j, (name, _, model) in enumerate(STAGES):
            recv = stamp + int((5 + 15 * j + rng.uniform(0, 5)) * 1e6)
            # only the header and the tracks are read: any other stage's message stands in as Detections
            msg = Tracks(header=header, tracks=people) if model is Tracks else Detections(header=header)
            monitor.record(name, msg, recv)
            last = recv / 1e9
    for name, _, _ in STAGES:
        monitor.statuses[name] = ServiceStatus(header=Header(stamp_ns=T0_NS), name=name, received=123456, published=123450, dropped=12, invalid=0)
    return monitor, last


def _too_wide(text: str) -> list[str]:
    return [line for line in text.split("\n") if len(line) > WIDTH]


def test_a_10_hz_stream_reads_10_hz_as_on_the_page() -> None:
    monitor, last = _fed_monitor()
    # polled half a second after the last frame, as the demo does: the rate is the stream's, not the poll's
    now = last + 0.5
    for name, _, _ in STAGES:
        assert monitor.meters[name].rate_hz(now) == pytest.approx(10.0, abs=0.2)
        assert monitor.summary()[name]["rate_hz"] == pytest.approx(10.0, abs=0.2)
    text = monitor.render("perception demo: still, 320x240 at 10 fps, 30 s (Ctrl-C stops)", 20.0, now=now)
    assert "tracks published at  10.0 Hz" in text
    # the page's meter, fed the same arrivals, reads the same
    page = StageMeter()
    page.arrived(t / 10 for t in range(200))
    assert page.rate_hz(19.9 + 0.5) == pytest.approx(10.0, abs=0.2)


def test_the_live_table_lists_tracks_by_state_within_80_columns() -> None:
    monitor, last = _fed_monitor()
    title = ("perception demo: people-following, 640x480 at 10 fps, 120 s (Ctrl-C stops)\n"
             "the live page: http://127.0.0.1:8080/")
    text = monitor.render(title, 123.4, now=last + 0.2)
    assert _too_wide(text) == []
    lines = text.split("\n")
    heads = [line for line in lines if line.split(" (")[0] in ("confirmed", "coasting", "tentative")]
    assert heads == ["confirmed (2)", "coasting (1)", "tentative (1)"]
    coasting = lines.index("coasting (1)")
    assert lines[coasting + 2].split()[0] == "2"  # the coasting track is under its own heading
    assert "speed (m/s)" in text and "0.50" in text  # |(0.4, -0.3)| = 0.5 m/s
    assert "(no status yet)" not in text


def test_the_closing_tables_fit_80_columns() -> None:
    monitor, _ = _fed_monitor(3.0)
    rng = np.random.default_rng(1)
    gt_rows = [(f, p, np.array([p + 0.1 * f, 1.0, 1.0])) for f in range(1, 301) for p in (1, 2, 3)]
    hyp_rows = [(f, p + (10 if f > 150 and p == 2 else 0), pos + rng.normal(0, 0.1, 3)) for f, p, pos in gt_rows
                if rng.uniform() > 0.1]
    report, table = score_rows(gt_rows, hyp_rows, "people-following", width=WIDTH)
    table += "\n\n" + pose_line({"posture_pairs": 612, "posture_accuracy": 0.85, "orientation_pairs": 598,
                                  "orientation_error_deg_p50": 22.5})
    attention = {"person_id": 1, "center_error_px_p50": 12.3, "center_error_px_p95": 45.6,
                 "target_visible_fraction": 0.97, "frames": 300}
    text = closing_text(monitor.render_summary(), table, Path("/tmp/perception-demo-abcdefgh"),
                        {"detector": 12.5, "detector-slow": 30.1, "localizer": 3.2, "embedder": 8.4, "tracker": 4.4,
                         "detector-back": 12.0, "localizer-back": 3.0, "embedder-back": 8.0},
                        [attention_line(attention)], "/tmp/perception-demo-abcdefgh/tracks.png")
    assert _too_wide(text) == []
    for column in ("objects", "misses%", "IDSW", "recall err", "MOTP (m)", "MOTA%", "IDF1%", "consistency%",
                   "ID histogram", "HOTA%", "LocA%"):
        assert column in text
    assert f"{100 * report['sequences']['people-following']['mota']:.2f}" in text
    assert "identity: people came back 0 times" in text and report["identity"]["returns"] == 0


def test_the_closing_text_says_what_the_people_who_came_back_were_given() -> None:
    """Person 1 leaves for 5 s and comes back with their ID; person 2 leaves and comes back as
    a new track; person 3 arrives later and is given person 2's first ID."""
    def rows(who: int, frames: range, track: int) -> list[tuple[int, int, int, np.ndarray]]:
        return [(f, who, track, np.array([who * 2.0, 0.0, 1.0])) for f in frames]

    people = (rows(1, range(1, 50), 1) + rows(1, range(100, 150), 1) + rows(2, range(1, 50), 2)
              + rows(2, range(100, 150), 5) + rows(3, range(160, 200), 2))
    _, text = score_rows([(f, w, p) for f, w, _, p in people], [(f, t, p) for f, _, t, p in people], "still",
                         width=WIDTH)
    assert ("identity: people came back 2 times (after 10 frames or more out of view):\n"
            "  1 got their own ID, 1 a new one, 0 someone else's\n"
            "  newcomers given an old ID: 1; track IDs covering two people: 1") in text
    assert _too_wide(text) == []
    assert text.count("final state") == 0
