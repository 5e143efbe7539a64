"""Embedder configuration: which backend, how to feed an ONNX model, how much to buffer.

Layered by :func:`common.runtime.config.load_config`: defaults -> file (section ``embedder``) ->
environment ``PERCEPTION_EMBEDDER__FIELD`` (nested with ``__``, e.g.
``PERCEPTION_EMBEDDER__ONNX__PATH``) -> CLI flags.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

from pydantic import ConfigDict, model_validator

from common.runtime.settings import AdvancedBlock, setting

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


class ThresholdsConfig(AdvancedBlock):
    """Tracker thresholds on the model's distance scale (from ``perception calibrate-embedder``)."""

    model_config = ConfigDict(extra="forbid")
    t_lower: float = setting(..., "below this distance, appearance alone accepts an association", ge=0.0)
    t_upper: float = setting(..., "at or above it, an association is refused; between, it needs spatial confirmation", gt=0.0)
    t_recover: float = setting(..., "a remembered ID is re-used below this distance", gt=0.0)

    @model_validator(mode="after")
    def _ordered(self) -> ThresholdsConfig:
        if not self.t_lower < self.t_upper:
            raise ValueError(f"t_lower ({self.t_lower}) must be below t_upper ({self.t_upper})")
        return self

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.t_lower, self.t_upper, self.t_recover)


class OnnxConfig(AdvancedBlock):
    """How to run an ONNX Re-ID model. A ``MODEL.json`` next to ``MODEL.onnx`` (as written
    by ``perception export-embedder``) supplies values not set here."""

    model_config = ConfigDict(extra="forbid")
    path: str = setting("", "the .onnx file")
    name: str = setting(_D.name, "model card name (default: the file name without .onnx)")
    input_size: tuple[int, int] = setting(_D.input_size, "(H, W) the crops are resized to")
    channel_order: Literal["rgb", "bgr"] = setting(_D.channel_order, "the channel order the model takes")
    scale: float = setting(_D.scale, "pixel scale before mean/std", gt=0.0)
    mean: tuple[float, float, float] = setting(_D.mean, "per-channel mean: (pixel * scale - mean) / std")
    std: tuple[float, float, float] = setting(_D.std, "per-channel standard deviation, positive")
    normalize: bool = setting(_D.normalize, "L2-normalise the outputs")
    metric: Literal["euclidean", "cosine"] = setting(_D.metric, "the distance the descriptors are compared with")
    thresholds: ThresholdsConfig | None = setting(None, "the model's recommended thresholds on its distance scale")
    providers: list[str] | None = setting(None, "e.g. [CUDAExecutionProvider, CPUExecutionProvider]; default: "
                                          "TensorRT, CUDA, CPU as available")
    intra_op_threads: int = setting(_D.intra_op_threads, "CPU threads (0 = onnxruntime's default)", ge=0, advanced=True)

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


class DepthMaskConfig(AdvancedBlock):
    """Depth cuts the background: each crop is masked to the pixels near the person's depth
    (the localizer's percentile) before it is described, when the frame has depth."""

    model_config = ConfigDict(extra="forbid")
    enabled: bool = setting(True, "mask crops by depth when the frame carries depth")
    percentile: float = setting(_M.percentile, "the person's depth: this percentile of the box's valid depth",
                                ge=0.0, le=100.0, advanced=True)
    near_m: float = setting(_M.near_m, "keep pixels this much in front of it", unit="m", ge=0.0, advanced=True)
    far_m: float = setting(_M.far_m, "and this much behind it", unit="m", gt=0.0, advanced=True)
    unknown_weight: float = setting(_M.unknown_weight, "weight of pixels without depth", ge=0.0, le=1.0, advanced=True)
    min_valid_pixels: int = setting(_M.min_valid_pixels, "fewer valid depth pixels in a box: described unmasked",
                                    ge=1, advanced=True)
    min_kept_fraction: float = setting(_M.min_kept_fraction, "a mask keeping less of its box is not used",
                                       ge=0.0, le=1.0, advanced=True)
    depth_unit_m: float = setting(_M.depth_unit_m, "metres per unit of integer depth", unit="m", gt=0.0)

    def params(self) -> DepthMaskParams:
        """The core's parameters."""
        return DepthMaskParams(**self.model_dump(exclude={"enabled"}))


class OrientationConfig(AdvancedBlock):
    """An optional ONNX classifier of the upper body's orientation on each crop (TU Ilmenau):
    (N, 3, H, W) in, (N, 8) scores out, bins relative to the camera (see
    services/embedder/core/orientation.py)."""

    model_config = ConfigDict(extra="forbid")
    path: str | None = setting(None, "the ONNX model; null: no orientation classifier")
    input_size: tuple[int, int] = setting((128, 64), "network input (H, W)")
    channel_order: Literal["rgb", "bgr"] = setting("rgb", "the channel order the classifier takes")
    outputs: Literal["logits", "probabilities"] = setting("logits", "what the model outputs")

    def params(self) -> OrientationParams | None:
        if not self.path:
            return None
        return OrientationParams(path=self.path, input_size=self.input_size, channel_order=self.channel_order,
                                 outputs=self.outputs)


class EmbedderConfig(AdvancedBlock):
    """Settings of ``perception embedder``."""

    model_config = ConfigDict(extra="forbid")
    backend: Literal["colour", "onnx"] = setting("colour", "colour (no model: colour histograms) or onnx (a Re-ID model, onnx.path)")
    camera: str = setting("head", "camera whose frames and detections are embedded", min_length=1)
    onnx: OnnxConfig = setting(description="the onnx backend's model", default_factory=OnnxConfig)
    thresholds: ThresholdsConfig | None = setting(None, "override the model card's thresholds")
    frame_buffer: int = setting(8, "recent frames kept to pair with detections", ge=1, le=256, advanced=True)
    max_lag_s: float = setting(0.5, "detections older than the newest frame by more than this are dropped as stale "
                               "instead of being embedded late", unit="s", gt=0.0, advanced=True)
    min_crop_px: int = setting(4, "crops narrower or lower than this are not described (counted as tiny_crops)",
                               unit="px", ge=1, advanced=True)
    depth_mask: DepthMaskConfig = setting(description="crops masked to the person's depth",
                                         default_factory=DepthMaskConfig)
    orientation: OrientationConfig = setting(description="the optional orientation classifier",
                                             default_factory=OrientationConfig)

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
