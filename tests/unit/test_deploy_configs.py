"""Every service config in deploy/ is valid for the service that will read it."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from pydantic import BaseModel

from common.runtime.config import load_config
from services.detector.config import DetectorConfig
from services.embedder.config import EmbedderConfig
from services.localizer.config import LocalizerConfig
from services.tracker.config import TrackerConfig
from tools.launcher.launchfile import load_launch_file

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"
MODELS: dict[str, type[BaseModel]] = {
    "detector": DetectorConfig,
    "localizer": LocalizerConfig,
    "embedder": EmbedderConfig,
    "tracker": TrackerConfig,
}


@pytest.mark.parametrize("launch_file", sorted(DEPLOY.glob("*.yaml")), ids=lambda p: p.name)
def test_inline_service_configs_validate(launch_file: Path, tmp_path: Path) -> None:
    launch = load_launch_file(launch_file, environ={})
    for spec in launch.services:
        model = MODELS.get(spec.command or "")
        if model is None or spec.config is None:
            continue
        if isinstance(spec.config, dict):
            cfg_file = tmp_path / f"{spec.name}.yaml"
            cfg_file.write_text(yaml.safe_dump(spec.config))
        else:
            cfg_file = Path(spec.config)
        load_config(model, cfg_file)  # raises ConfigError naming the bad key


def test_the_two_camera_deploy_file_uses_the_several_camera_tracker_settings() -> None:
    from services.tracker.presets import load_preset

    launch = load_launch_file(DEPLOY / "two-cameras.yaml", environ={})
    tracker = next(s for s in launch.services if s.command == "tracker")
    assert isinstance(tracker.config, dict) and tracker.config["robust"] == load_preset("several-cameras")["robust"]
