"""Each node's default config gives its core the core's own defaults.

Every default is written once, in the core's params dataclass; the pydantic configs read
it from there. These tests build the core params from each node's default config through
the method its service uses, and compare every field with the core dataclass's default,
so an edit that makes the two disagree fails here. Deliberate differences are listed
(``exceptions``) with the reason.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from services.detector.config import DetectorConfig
from services.detector.core.darknet import DarknetParams
from services.detector.core.depth import DepthParams
from services.detector.core.ground import GroundParams
from services.detector.core.hog import HogParams
from services.detector.core.yolo_onnx import YoloParams
from services.embedder.config import EmbedderConfig, with_sidecar
from services.embedder.core.onnx_model import OnnxParams
from services.localizer.config import LocalizerConfig
from services.localizer.core import DepthNoiseModel, LocalizerParams
from services.tracker.config import TrackerConfig
from services.tracker.core import AppearanceGate


def core_defaults(cls: type) -> dict[str, Any]:
    """The defaults of a dataclass's fields (fields without one are left out)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            out[f.name] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            out[f.name] = f.default_factory()
    return out


def differences(params: Any, exceptions: dict[str, Any] | None = None) -> dict[str, tuple[Any, Any]]:
    """{field: (got, wanted)} for every field of ``params`` that is not the core's default
    (or the listed exception). Fields the core requires must be listed as exceptions."""
    want = {**core_defaults(type(params)), **(exceptions or {})}
    names = [f.name for f in dataclasses.fields(params)]
    unlisted = [n for n in names if n not in want]
    assert not unlisted, f"{type(params).__name__}: required fields {unlisted} need an expected value"
    return {n: (getattr(params, n), want[n]) for n in names if getattr(params, n) != want[n]}


def test_helpers_see_a_difference() -> None:
    assert differences(HogParams(upsample=2.0)) == {"upsample": (2.0, 1.0)}
    assert differences(DepthParams(ground=GroundParams(window_m=1.0)))["ground"][1] == GroundParams()


# ------------------------------------------------------------------- tracker
def test_tracker_defaults() -> None:
    config = TrackerConfig(memory_path=None)
    # Exception: gate and t_recover are the embedding model's thresholds, not defaults.
    # Position-only (no thresholds) there is no gate and t_recover is 0, unused; the
    # core's t_recover default (400) is TriNet's.
    assert differences(config.thesis.params(None, config.memory_size), {"gate": None, "t_recover": 0.0}) == {}


def test_tracker_gate_defaults() -> None:
    config = TrackerConfig(memory_path=None)
    th = config.thresholds("colour")
    assert th is not None and th.s_max is None  # the colour model uses the config's s_max
    params = config.thesis.params(config.appearance_model(th), config.memory_size)
    assert params.gate is not None
    gate_defaults = core_defaults(AppearanceGate)
    assert (params.gate.s_max, params.gate.inf) == (gate_defaults["s_max"], gate_defaults["inf"])
    assert differences(params, {"gate": params.gate, "t_recover": th.t_recover}) == {}


# ----------------------------------------------------------------- localizer
def test_localizer_defaults() -> None:
    params = LocalizerConfig().params()
    assert differences(params) == {}
    assert differences(params.noise) == {}
    assert differences(LocalizerConfig().floor_params()) == {}
    assert params.noise == DepthNoiseModel() and params == LocalizerParams()


# ------------------------------------------------------------------ detector
def test_detector_defaults() -> None:
    config = DetectorConfig()
    assert differences(config.hog.params()) == {}
    depth = config.depth.params()
    assert differences(depth) == {}
    assert differences(depth.ground) == {}
    # Model files are required in the core: None until the config names them.
    assert differences(config.yolo.params(), {"model": None}) == {}
    assert differences(config.darknet.params(), {"cfg": None, "weights": None}) == {}
    assert {YoloParams, DarknetParams} == {type(config.yolo.params()), type(config.darknet.params())}


# ------------------------------------------------------------------ embedder
def test_embedder_defaults(tmp_path: Path) -> None:
    config = EmbedderConfig()
    # The model path is required in the core: "" until the config names a file.
    assert differences(config.onnx.params(), {"path": ""}) == {}
    # build_backend reads a MODEL.json beside the model first; without one nothing changes.
    onnx = config.onnx.model_copy(update={"path": str(tmp_path / "model.onnx")})
    assert differences(with_sidecar(onnx).params(), {"path": onnx.path}) == {}
    assert isinstance(config.onnx.params(), OnnxParams)


def test_localizer_config_names_an_inverted_occluder_range() -> None:
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="occluder_gap_m .* must not exceed occluder_max_gap_m"):
        LocalizerConfig(occluder_gap_m=3.0, occluder_max_gap_m=2.0)
