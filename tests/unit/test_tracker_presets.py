"""The tracker's presets (deploy/presets/*.yaml): each loads and validates, ``--preset`` layers one
between the defaults and ``--service-config``, and an unknown name stops the command naming the
presets there are."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from common.runtime.node import load_node_config
from perception.cli import main
from services.tracker import flags
from services.tracker.config import TrackerConfig
from services.tracker.presets import PRESETS_DIR, PresetError, load_preset, preset_environment, preset_names


def test_every_preset_is_a_valid_layer_of_tracker_settings_with_a_comment_first() -> None:
    assert {"several-cameras", "pets-site"} <= set(preset_names())
    for name in preset_names():
        text = (PRESETS_DIR / f"{name}.yaml").read_text()
        assert text.startswith(f'# Tracker preset "{name}"'), f"{name}.yaml: say where it fits and what it was measured on"
        assert "Measured on" in text
        config = TrackerConfig.model_validate({**load_preset(name), "memory_path": None})
        assert config.model_dump(exclude_unset=True)  # it changes something


def test_the_presets_values() -> None:
    several = TrackerConfig.model_validate(load_preset("several-cameras")).robust
    assert (several.max_coast_unseen_s, several.max_position_var_unseen, several.handover_gate_sq) == (6.0, 100.0, 13.8)
    assert TrackerConfig.model_validate(load_preset("pets-site")).robust.recovery.left_weight == 0.3
    assert preset_environment("pets-site") == {"PERCEPTION_TRACKER__ROBUST__RECOVERY__LEFT_WEIGHT": "0.3"}


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    flags.add_arguments(parser)
    return parser.parse_args(list(argv))


def test_a_preset_sits_between_the_defaults_and_the_service_config(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    args = _args("--preset", "several-cameras")
    config = load_node_config(TrackerConfig, "tracker", None, flags.overrides(args), flags.preset(args))
    assert config.robust.max_coast_unseen_s == 6.0 and config.robust.handover_gate_sq == 13.8
    assert config.robust.max_coast_s == TrackerConfig().robust.max_coast_s  # the rest: the defaults
    file = tmp_path / "tracker.yaml"
    file.write_text("tracker:\n  robust:\n    max_coast_unseen_s: 4.0\n")
    args = _args("--preset", "several-cameras", "--service-config", str(file))
    config = load_node_config(TrackerConfig, "tracker", args.service_config, flags.overrides(args), flags.preset(args))
    assert config.robust.max_coast_unseen_s == 4.0  # the file over the preset
    assert config.robust.max_position_var_unseen == 100.0  # the preset's others stay
    monkeypatch.setenv("PERCEPTION_TRACKER__ROBUST__HANDOVER_GATE_SQ", "9.2")
    config = load_node_config(TrackerConfig, "tracker", args.service_config, flags.overrides(args), flags.preset(args))
    assert config.robust.handover_gate_sq == 9.2  # the environment over both
    assert flags.preset(_args()) is None


def test_an_unknown_preset_is_refused_naming_the_known_ones(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    with pytest.raises(PresetError, match="no tracker preset 'nope'; the presets: .*pets-site.*several-cameras"):
        load_preset("nope")
    with pytest.raises(PresetError):
        load_preset("../presets/pets-site")
    assert main(["tracker", "--preset", "nope"]) != 0
    assert "pets-site" in capsys.readouterr().err
    dets = tmp_path / "dets.csv"
    dets.write_text("frame,stamp,x,y,z,score\n0,0.0,1.0,1.0,1.0,0.9\n")
    assert main(["track", "--detections", str(dets), "--output", str(tmp_path / "out.csv"), "--preset", "nope"]) != 0
    assert "several-cameras" in capsys.readouterr().err


def test_perception_track_reads_a_preset(tmp_path: Path) -> None:
    dets, out = tmp_path / "dets.csv", tmp_path / "out.csv"
    dets.write_text("frame,stamp,x,y,z,score\n" + "".join(f"{k},{k / 10:.1f},1.0,1.0,1.0,0.9\n" for k in range(10)))
    assert main(["track", "--detections", str(dets), "--output", str(out), "--preset", "pets-site"]) == 0
    assert out.read_text().startswith("frame,stamp,id")
