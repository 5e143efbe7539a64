"""TrackerConfig: the tracker's settings, with seed 000's values as defaults (the core's
:class:`TrackerParams` defaults, written there only).

Appearance thresholds depend on the embedding model's distance scale, so they live under
the model's name in ``appearance``. :data:`DEFAULT_APPEARANCE` below is the one place the
shipped per-model values are written.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from services.tracker.core import AppearanceGate, TrackerParams

__all__ = ["DEFAULT_APPEARANCE", "DEFAULT_EMBEDDING_MODEL", "AppearanceConfig", "TrackerConfig", "default_memory_path"]

#: The project's default embedder (services/embedder): an L2-normalised colour histogram.
DEFAULT_EMBEDDING_MODEL = "colour"


class AppearanceConfig(BaseModel):
    """Algorithm 1 and 2 thresholds on one embedding model's distance scale."""

    model_config = ConfigDict(extra="forbid")

    t_lower: float = Field(ge=0.0, description="below: appearance alone admits a pair")
    t_upper: float = Field(gt=0.0, description="at or above: the pair is never admitted")
    t_recover: float = Field(gt=0.0, description="Algorithm 2: reuse a remembered ID closer than this")
    s_max: float | None = Field(default=None, ge=0.0, description="per-model S_max; None uses TrackerConfig.s_max")

    @model_validator(mode="after")
    def _ordered(self) -> AppearanceConfig:
        if not self.t_lower < self.t_upper:
            raise ValueError(f"t_lower ({self.t_lower}) must be below t_upper ({self.t_upper})")
        return self


# --------------------------------------------------------------------------------------
# Shipped thresholds, per embedding model. THE place to change them.
#  * trinet: seed 000 (eq. 17 and 18), in TriNet's raw 128-D feature scale.
#  * colour: the default colour-histogram embedder; L2-normalised, so distances lie in
#    [0, sqrt(2)]. Calibrated on PETS09 crops and synthetic lighting changes with
#    `perception calibrate-embedder`; the embedder's model card carries the same values
#    (services/embedder/core/colour.py, COLOUR_THRESHOLDS; a test keeps them equal).
DEFAULT_APPEARANCE: dict[str, dict[str, float]] = {
    "trinet": {"t_lower": 300.0, "t_upper": 700.0, "t_recover": 400.0, "s_max": 0.05},
    "colour": {"t_lower": 0.35, "t_upper": 0.85, "t_recover": 0.40},
}
# --------------------------------------------------------------------------------------


def default_memory_path() -> Path:
    """``$XDG_STATE_HOME/people-perception/tracker-id-memory.npz`` (``~/.local/state`` by default)."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "people-perception" / "tracker-id-memory.npz"


def _default_appearance() -> dict[str, AppearanceConfig]:
    return {k: AppearanceConfig(**v) for k, v in DEFAULT_APPEARANCE.items()}


#: The core's defaults: every default below that the core also has is taken from here,
#: so it is written once, in the core (tests/test_config_defaults.py checks they agree).
_D = TrackerParams()
_S_MAX = next(f.default for f in dataclasses.fields(AppearanceGate) if f.name == "s_max")


class TrackerConfig(BaseModel):
    """Everything ``perception tracker`` and ``perception track`` can be told."""

    model_config = ConfigDict(extra="forbid")

    # --- Kalman filter (seed 000, III-C)
    sigma0: tuple[float, float, float, float, float, float] = Field(
        default=_D.sigma0, description="initial std of (x, y, z, vx, vy, vz); P0 = diag(sigma0^2)")
    sigma_q: tuple[float, float, float, float, float, float] = Field(
        default=_D.sigma_q, description="process noise std per nominal frame; Q = diag(sigma_q^2)")
    sigma_r: tuple[float, float, float] = Field(default=_D.sigma_r, description="measurement noise std (m)")
    use_detection_covariance: bool = Field(
        default=False, description="use each LocalizedDetection's covariance as R instead of sigma_r")
    time_step: Literal["time", "frame"] = Field(
        default=_D.time_step, description="'time': dt from stamps; 'frame': dt = 1 per frame, as the thesis")
    frame_period_s: float = Field(default=_D.frame_period_s, gt=0.0, le=10.0,
                                  description="nominal frame period: Q and miss counts are per this period")
    # --- association (Algorithm 1) and ID memory (Algorithm 2)
    embedding_model: str | None = Field(
        default=None, min_length=1, description="accept descriptors of this model only; None: the first model seen")
    appearance: dict[str, AppearanceConfig] = Field(default_factory=_default_appearance)
    s_max: float = Field(default=_S_MAX, ge=0.0,
                         description="S_max: max squared Mahalanobis (x, y) in the ambiguous band")
    infinite_cost: float = Field(default=_D.inf, gt=0.0, description="cost of an inadmissible pair")
    position_gate_probability: float = Field(default=_D.position_gate_probability, gt=0.0, lt=1.0,
                                             description="chi-square (2 dof) gate of position-only association")
    # --- life cycle (seed 000, III-E)
    n_init: int = Field(default=_D.n_init, ge=1, le=100, description="consecutive associated frames to confirm")
    max_misses: int = Field(default=_D.max_misses, ge=1, le=1000, description="frames without association to delete")
    # --- bounded memory (seed 001)
    gallery_size: int = Field(default=_D.gallery_size, ge=1, le=100_000,
                              description="max descriptors per track gallery")
    memory_size: int = Field(default=_D.memory_size, ge=1, le=100_000, description="max descriptors per remembered ID")
    # --- service
    camera: str = Field(default="head", min_length=1, description="camera whose streams to track ('*' for all)")
    frame_id: str = Field(default="map", min_length=1, description="tracking frame; inputs in another frame are dropped")
    join_wait_s: float = Field(default=0.1, ge=0.0, le=10.0,
                               description="how long localized detections wait for their embeddings")
    reorder_window_s: float = Field(default=0.5, ge=0.0, le=10.0,
                                    description="inputs older than this behind the newest are dropped")
    memory_path: Path | None = Field(default_factory=default_memory_path,
                                     description="ID memory file, loaded at start and rewritten on change; null: none")
    memory_save_period_s: float = Field(default=2.0, gt=0.0, le=3600.0,
                                        description="how often live tracks' galleries are also written")

    @field_validator("sigma0", "sigma_q", "sigma_r")
    @classmethod
    def _positive(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if any(not (s > 0) for s in v):
            raise ValueError(f"every standard deviation must be positive, got {v}")
        return v

    @field_validator("appearance", mode="before")
    @classmethod
    def _merge_defaults(cls, v: object) -> object:
        """Models named in a file are added to (or override) the shipped ones."""
        if isinstance(v, dict):
            return {**DEFAULT_APPEARANCE, **v}
        return v

    @field_validator("camera")
    @classmethod
    def _camera(cls, v: str) -> str:
        if v != "*" and any(c in v for c in "/*$?# "):
            raise ValueError(f"camera {v!r} must be a name without '/', '*', '$', '?', '#' or spaces, or '*'")
        return v

    def thresholds(self, model: str) -> AppearanceConfig | None:
        """The configured thresholds of ``model``, or None."""
        return self.appearance.get(model)

    def gate(self, th: AppearanceConfig) -> AppearanceGate:
        return AppearanceGate(th.t_lower, th.t_upper, self.s_max if th.s_max is None else th.s_max, self.infinite_cost)

    def params(self, thresholds: AppearanceConfig | None) -> TrackerParams:
        """The core's parameters; ``thresholds`` None means position-only association.

        ``gate`` and ``t_recover`` come from the embedding model's thresholds, not from the
        core's defaults (the core's ``t_recover`` 400 is TriNet's): position-only, there is
        no gate and ``t_recover`` is 0 (unused: no descriptor is ever compared).
        """
        return TrackerParams(
            sigma0=self.sigma0, sigma_q=self.sigma_q, sigma_r=self.sigma_r,
            gate=self.gate(thresholds) if thresholds is not None else None,
            t_recover=thresholds.t_recover if thresholds is not None else 0.0,
            n_init=self.n_init, max_misses=self.max_misses, time_step=self.time_step,
            frame_period_s=self.frame_period_s, gallery_size=self.gallery_size, memory_size=self.memory_size,
            position_gate_probability=self.position_gate_probability, inf=self.infinite_cost,
        )
