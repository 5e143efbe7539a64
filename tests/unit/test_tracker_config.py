"""The tracker's settings: one section per profile, the old flat thesis keys, and the one
interface both profiles' cores are built and driven through."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from common.runtime.config import ConfigError, load_config
from services.tracker.config import ThesisConfig, TrackerConfig
from services.tracker.core import RobustTracker, ThesisTracker, TrackerCore
from services.tracker.core.types import FrameInput, KeptMemory


def test_each_profile_has_its_section_and_each_setting_is_written_once() -> None:
    top = set(TrackerConfig.model_fields)
    assert {"robust", "thesis"} <= top
    for name in ("n_init", "gallery_size", "sigma_r", "time_step", "s_max"):
        assert name not in top, name
        assert name in ThesisConfig.model_fields, name
    cfg = TrackerConfig(memory_path=None, profile="thesis", thesis={"n_init": 5, "gallery_size": 7})
    tracker = cfg.build_tracker(cfg.thresholds("colour"))
    assert isinstance(tracker, ThesisTracker) and (tracker.params.n_init, tracker.params.gallery_size) == (5, 7)
    assert tracker.params.gate is not None and tracker.params.gate.s_max == cfg.thesis.s_max


def test_old_flat_thesis_keys_still_load_under_thesis(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "tracker.yaml"
    path.write_text("tracker:\n  n_init: 4\n  time_step: frame\n  robust: {n_init: 2}\n")
    with caplog.at_level(logging.WARNING, logger="services.tracker.config"):
        cfg = load_config(TrackerConfig, path, section="tracker")
    assert (cfg.thesis.n_init, cfg.thesis.time_step, cfg.robust.n_init) == (4, "frame", 2)
    assert "under 'thesis:'" in caplog.text and "n_init" in caplog.text
    path.write_text("tracker:\n  n_init: 4\n  thesis: {n_init: 3}\n")
    with pytest.raises(ConfigError, match="both at the top and under 'thesis:'"):
        load_config(TrackerConfig, path, section="tracker")


def test_a_bad_old_flat_key_names_its_new_place_and_its_line(tmp_path: Path) -> None:
    path = tmp_path / "tracker.yaml"
    path.write_text("profile: thesis\nn_init: 3\nframe_period_s: -5\n")
    with pytest.raises(ConfigError) as err:
        load_config(TrackerConfig, path)
    assert "thesis.frame_period_s" in str(err.value) and "line 3" in str(err.value)


@pytest.mark.parametrize("profile, cls", [("robust", RobustTracker), ("thesis", ThesisTracker)])
def test_both_profiles_are_one_interface(profile: str, cls: type) -> None:
    cfg = TrackerConfig(memory_path=None, profile=profile)
    tracker: TrackerCore = cfg.build_tracker(None)
    assert type(tracker) is cls and TrackerCore in cls.__mro__
    cfg.apply_thresholds(tracker, cfg.appearance["colour"])
    look = np.ones((1, 4), np.float32) / 2.0
    for k in range(4):
        result = tracker.step(0.1 * k, FrameInput.of(np.array([[1.0, 2.0, 1.0]]), look, scores=np.array([0.9])))
    assert [v.id for v in tracker.reported(result)] == [1] and tracker.live_ids() == {1}
    assert [i for i, _ in tracker.export_memory().live_galleries] == [1]
    state = tracker.snapshot()
    assert tracker.restart_clock() == [1] and tracker.live_ids() == set() and 1 in tracker.memory
    tracker.restore(state)
    assert tracker.live_ids() == {1}
    ahead = tracker.predict_reports(tracker.reported(result), 0.5)
    assert ahead[0].position[0] == pytest.approx(result.tracks[0].position[0] + 0.5 * result.tracks[0].velocity[0])
    tracker.import_memory(KeptMemory(classifiers={}, recovery=None))
    assert isinstance(tracker.export_memory().classifiers, dict)
    assert tracker.forget(1)["live_track"] and not tracker.export_memory().live_galleries
