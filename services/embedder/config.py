"""Embedder configuration: which backend, how to feed an ONNX model, how much to buffer.

Layered by :func:`common.runtime.config.load_config`: defaults -> file (section ``embedder``) ->
environment ``PERCEPTION_EMBEDDER__FIELD`` (nested with ``__``, e.g.
``PERCEPTION_EMBEDDER__ONNX__PATH``) -> CLI flags.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from common.runtime.config import ConfigError
from services.embedder.core.backend import Backend, EmbedderError
from services.embedder.core.depth_mask import DepthMaskParams
from services.embedder.core.onnx_model import OnnxEmbedder, OnnxParams
from services.embedder.core.orientation import OrientationParams

__all__ = ["DepthMaskConfig", "EmbedderConfig", "OnnxConfig", "ThresholdsConfig", "build_backend", "sidecar_path",
           "with_sidecar"]

#: The core's defaults, read by :class:`OnnxConfig` so each is written once, in the core
#: (tests/unit/test_config_defaults.py checks they agree). ``path`` is required in the core and
#: "" here until configured: the placeholder is unused. ``thresholds`` and ``providers``
#: None are "not given" in both (other types here than there).
_D = OnnxParams(path="")
_M = DepthMaskParams()


class ThresholdsConfig(BaseModel):
    """Tracker thresholds on the model's distance scale (from ``perception calibrate-embedder``)."""

    model_config = ConfigDict(extra="forbid")
    t_lower: float = Field(ge=0.0)
    t_upper: float = Field(gt=0.0)
    t_recover: float = Field(gt=0.0)

    @model_validator(mode="after")
    def _ordered(self) -> ThresholdsConfig:
        if not self.t_lower < self.t_upper:
            raise ValueError(f"t_lower ({self.t_lower}) must be below t_upper ({self.t_upper})")
        return self

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.t_lower, self.t_upper, self.t_recover)


class OnnxConfig(BaseModel):
    """How to run an ONNX Re-ID model. A ``MODEL.json`` next to ``MODEL.onnx`` (as written
    by ``perception export-embedder``) supplies values not set here."""

    model_config = ConfigDict(extra="forbid")
    path: str = Field(default="", description="the .onnx file")
    name: str = Field(default=_D.name, description="model card name (default: the file name without .onnx)")
    input_size: tuple[int, int] = Field(default=_D.input_size, description="(H, W) the crops are resized to")
    channel_order: Literal["rgb", "bgr"] = _D.channel_order
    scale: float = Field(default=_D.scale, gt=0.0, description="pixel scale before mean/std")
    mean: tuple[float, float, float] = _D.mean
    std: tuple[float, float, float] = _D.std
    normalize: bool = Field(default=_D.normalize, description="L2-normalise the outputs")
    metric: Literal["euclidean", "cosine"] = _D.metric
    thresholds: ThresholdsConfig | None = None
    providers: list[str] | None = Field(default=None, description="e.g. [CUDAExecutionProvider, CPUExecutionProvider]; "
                                        "default: TensorRT, CUDA, CPU as available")
    intra_op_threads: int = Field(default=_D.intra_op_threads, ge=0,
                                  description="CPU threads (0 = onnxruntime's default)")

    @model_validator(mode="after")
    def _sizes(self) -> OnnxConfig:
        if min(self.input_size) <= 0:
            raise ValueError(f"input_size must be positive (H, W), got {self.input_size}")
        if min(self.std) <= 0:
            raise ValueError("std must be positive")
        return self

    def params(self) -> OnnxParams:
        """The core's parameters (apply :func:`with_sidecar` first for the model's ``MODEL.json``)."""
        return OnnxParams(
            path=self.path, name=self.name, input_size=self.input_size, channel_order=self.channel_order,
            scale=self.scale, mean=self.mean, std=self.std, normalize=self.normalize, metric=self.metric,
            thresholds=self.thresholds.as_tuple() if self.thresholds else None,
            providers=tuple(self.providers) if self.providers else None, intra_op_threads=self.intra_op_threads)


class DepthMaskConfig(BaseModel):
    """Depth cuts the background: each crop is masked to the pixels near the person's depth
    (the localizer's percentile) before it is described, when the frame has depth."""

    model_config = ConfigDict(extra="forbid")
    enabled: bool = Field(default=True, description="mask crops by depth when the frame carries depth")
    percentile: float = Field(default=_M.percentile, ge=0.0, le=100.0,
                              description="the person's depth: this percentile of the box's valid depth")
    near_m: float = Field(default=_M.near_m, ge=0.0, description="keep pixels this much in front of it")
    far_m: float = Field(default=_M.far_m, gt=0.0, description="and this much behind it")
    unknown_weight: float = Field(default=_M.unknown_weight, ge=0.0, le=1.0,
                                  description="weight of pixels without depth")
    min_valid_pixels: int = Field(default=_M.min_valid_pixels, ge=1,
                                  description="fewer valid depth pixels in a box: described unmasked")
    min_kept_fraction: float = Field(default=_M.min_kept_fraction, ge=0.0, le=1.0,
                                     description="a mask keeping less of its box is not used")
    depth_unit_m: float = Field(default=_M.depth_unit_m, gt=0.0, description="metres per unit of integer depth")

    def params(self) -> DepthMaskParams:
        """The core's parameters."""
        return DepthMaskParams(**self.model_dump(exclude={"enabled"}))


class OrientationConfig(BaseModel):
    """An optional ONNX classifier of the upper body's orientation on each crop (TU Ilmenau):
    (N, 3, H, W) in, (N, 8) scores out, bins relative to the camera (see
    services/embedder/core/orientation.py)."""

    model_config = ConfigDict(extra="forbid")
    path: str | None = Field(default=None, description="the ONNX model; null: no orientation classifier")
    input_size: tuple[int, int] = Field(default=(128, 64), description="network input (H, W)")
    channel_order: Literal["rgb", "bgr"] = "rgb"
    outputs: Literal["logits", "probabilities"] = Field(default="logits", description="what the model outputs")

    def params(self) -> OrientationParams | None:
        if not self.path:
            return None
        return OrientationParams(path=self.path, input_size=self.input_size, channel_order=self.channel_order,
                                 outputs=self.outputs)


class EmbedderConfig(BaseModel):
    """Settings of ``perception embedder``."""

    model_config = ConfigDict(extra="forbid")
    backend: Literal["colour", "onnx"] = "colour"
    camera: str = Field(default="head", min_length=1, description="camera whose frames and detections are embedded")
    onnx: OnnxConfig = Field(default_factory=OnnxConfig)
    thresholds: ThresholdsConfig | None = Field(default=None, description="override the model card's thresholds")
    frame_buffer: int = Field(default=8, ge=1, le=256, description="recent frames kept to pair with detections")
    max_lag_s: float = Field(default=0.5, gt=0.0, description="detections older than the newest frame by more "
                             "than this are dropped as stale instead of being embedded late")
    min_crop_px: int = Field(default=4, ge=1, description="crops narrower or lower than this are not described "
                             "(counted as tiny_crops)")
    depth_mask: DepthMaskConfig = Field(default_factory=DepthMaskConfig)
    orientation: OrientationConfig = Field(default_factory=OrientationConfig)

    @model_validator(mode="after")
    def _onnx_path(self) -> EmbedderConfig:
        if self.backend == "onnx" and not self.onnx.path:
            raise ValueError("backend 'onnx' needs onnx.path (--model FILE.onnx)")
        return self


def sidecar_path(model_path: str | Path) -> Path:
    """``MODEL.json`` beside ``MODEL.onnx``."""
    return Path(model_path).expanduser().with_suffix(".json")


def with_sidecar(cfg: OnnxConfig) -> OnnxConfig:
    """``cfg`` with the values it leaves unset taken from the model's ``MODEL.json``, if any."""
    side = sidecar_path(cfg.path)
    if not side.is_file():
        return cfg
    try:
        data: dict[str, Any] = json.loads(side.read_text())
        merged = {**data, **cfg.model_dump(exclude_unset=True)}
        return OnnxConfig.model_validate(merged)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"model description {side} is unusable: {exc}") from exc


def build_backend(config: EmbedderConfig) -> Backend:
    """The configured backend, ready to run. Raises EmbedderError or ConfigError."""
    from dataclasses import replace

    backend: Backend
    if config.backend == "colour":
        from services.embedder.core.colour import ColourDescriptor

        backend = ColourDescriptor()
    else:
        backend = OnnxEmbedder(with_sidecar(config.onnx).params())
    if config.thresholds is not None:
        card = replace(backend.card, thresholds=config.thresholds.as_tuple())
        try:
            backend.card = card  # type: ignore[misc]
        except AttributeError as exc:
            raise EmbedderError(f"backend {type(backend).__name__} does not allow overriding its card") from exc
    return backend
