"""TrackerConfig: the tracker's settings. Each profile has its section, ``robust:`` and
``thesis:``, with the core's defaults (:class:`RobustParams`, :class:`TrackerParams`,
written there only); the service's settings and the ID memory's are at the top.

Appearance thresholds depend on the embedding model's distance scale, so they live under
the model's name in ``appearance``. :data:`DEFAULT_APPEARANCE` below is the one place the
shipped per-model values are written.

The thesis profile's settings used to sit at the top (``n_init: 3``); such files still load:
those keys are moved under ``thesis:``, with a warning that names the new place.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from services.tracker.core import AppearanceModel, ScoreModel, TrackerCore, TrackerParams
from services.tracker.core.identity import IdentityMemory
from services.tracker.profiles import ClassifierConfig, PostureConfig, RobustConfig, ScoreConfig, ThesisConfig

__all__ = ["DEFAULT_APPEARANCE", "DEFAULT_EMBEDDING_MODEL", "PROFILES", "SEVERAL_CAMERAS", "AppearanceConfig",
           "ClassifierConfig", "PostureConfig", "RobustConfig", "ScoreConfig", "ThesisConfig", "TrackerConfig",
           "default_memory_path"]

log = logging.getLogger(__name__)

#: The tracker's profiles: ``robust`` (the default, built from Pinto's thesis, the TU Ilmenau
#: framework, Basso/Munaro and Ban et al.) and ``thesis`` (Pinto's thesis exactly, for
#: comparison and reproduction).
PROFILES = ("robust", "thesis")

#: The project's default embedder (services/embedder): an L2-normalised colour histogram.
DEFAULT_EMBEDDING_MODEL = "colour"


class AppearanceConfig(BaseModel):
    """Algorithm 1 and 2 thresholds on one embedding model's distance scale."""

    model_config = ConfigDict(extra="forbid")

    t_lower: float = Field(ge=0.0, description="below: appearance alone admits a pair")
    t_upper: float = Field(gt=0.0, description="at or above: the pair is never admitted")
    t_recover: float = Field(gt=0.0, description="Algorithm 2: reuse a remembered ID closer than this")
    s_max: float | None = Field(default=None, ge=0.0, description="per-model S_max (thesis profile); None uses thesis.s_max")
    metric: Literal["euclidean", "cosine"] | None = Field(
        default=None, description="how the model's descriptors compare; None: as its model card says (euclidean if none)")

    @model_validator(mode="after")
    def _ordered(self) -> AppearanceConfig:
        if not self.t_lower < self.t_upper:
            raise ValueError(f"t_lower ({self.t_lower}) must be below t_upper ({self.t_upper})")
        return self


# --------------------------------------------------------------------------------------
# Shipped thresholds, per embedding model. THE place to change them.
#  * trinet: Pinto's thesis (eq. 17 and 18), in TriNet's raw 128-D feature scale.
#  * colour: the default colour-histogram embedder; L2-normalised, so distances lie in
#    [0, sqrt(2)]. Calibrated on PETS09 crops and synthetic lighting changes with
#    `perception calibrate-embedder`; the embedder's model card carries the same values
#    (services/embedder/core/colour.py, COLOUR_THRESHOLDS; a test keeps them equal).
DEFAULT_APPEARANCE: dict[str, dict[str, float]] = {
    "trinet": {"t_lower": 300.0, "t_upper": 700.0, "t_recover": 400.0, "s_max": 0.05},
    "colour": {"t_lower": 0.31, "t_upper": 0.75, "t_recover": 0.38},
}
# --------------------------------------------------------------------------------------


def default_memory_path() -> Path:
    """``$XDG_STATE_HOME/people-perception/tracker-id-memory.npz`` (``~/.local/state`` by default)."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "people-perception" / "tracker-id-memory.npz"


def _default_appearance() -> dict[str, AppearanceConfig]:
    return {k: AppearanceConfig(**v) for k, v in DEFAULT_APPEARANCE.items()}


#: The core's defaults: every default below that the core also has is taken from here,
#: so it is written once, in the core (tests/unit/test_config_defaults.py checks they agree).
_D = TrackerParams()

#: The robust settings for several cameras with blind stretches between their views (the
#: head camera and one on the base looking backwards): a track out of every view coasts up
#: to 6 s and 100 m^2 (about 3 s of walking at q_accel 3), and a person confirmed in one
#: camera's view takes the ID of a track that left another camera's view, by motion (the
#: chi2 gate of the association). ``deploy/two-cameras.yaml``, ``perception demo
#: --back-camera`` and ``run_chain(back_camera=...)`` use them. They are not the defaults: on
#: one moving camera (the head turning away from people, the base driving) the longer
#: coasting lets drifted predictions take the wrong person when the view comes back
#: (simulator moving-base IDF1 0.705 -> 0.643; moving-head 0.798 -> 0.797).
SEVERAL_CAMERAS: dict[str, float] = {"max_coast_unseen_s": 6.0, "max_position_var_unseen": 100.0,
                                     "handover_gate_sq": 13.8}


#: The thesis profile's settings that used to sit at the top of the tracker's settings.
_OLD_THESIS_KEYS = tuple(ThesisConfig.model_fields)


class TrackerConfig(BaseModel):
    """Everything ``perception tracker`` and ``perception track`` can be told."""

    model_config = ConfigDict(extra="forbid")

    profile: Literal["robust", "thesis"] = Field(
        default="robust",
        description="'robust' (default): cue fusion, staged association, life cycle in seconds; "
                    "'thesis': Pinto's thesis exactly")
    robust: RobustConfig = Field(default_factory=RobustConfig, description="the robust profile's settings")
    thesis: ThesisConfig = Field(default_factory=ThesisConfig, description="the thesis profile's settings")
    # --- appearance (both profiles) and the ID memory (Algorithm 2)
    embedding_model: str | None = Field(
        default=None, min_length=1, description="accept descriptors of this model only; None: the first model seen")
    appearance: dict[str, AppearanceConfig] = Field(default_factory=_default_appearance)
    # --- bounded memory (the TU Ilmenau framework)
    memory_size: int = Field(default=_D.memory_size, ge=1, le=100_000, description="max descriptors per remembered ID")
    max_remembered_ids: int = Field(default=10_000, ge=1, le=1_000_000,
                                    description="max IDs remembered; one more forgets the one archived longest ago")
    # --- service
    camera: str = Field(default="head", min_length=1, description="camera whose streams to track ('*' for all)")
    frame_id: str = Field(default="map", min_length=1, description="tracking frame; inputs in another frame are dropped")
    output_rate_hz: float = Field(
        default=10.0, ge=0.0, le=1000.0,
        description="Tracks published at this rate, predicted to the publish time (TU Ilmenau); 0: once per input frame")
    join_wait_s: float = Field(default=0.1, ge=0.0, le=10.0,
                               description="how long localized detections wait for their embeddings")
    no_embeddings: list[str] = Field(
        default_factory=list, description="streams no embedder reads (a second, slow detector's, e.g. head-hog): "
                                          "their frames are tracked by position at once, not after join_wait_s")
    view_age_s: float = Field(
        default=1.0, gt=0.0, le=60.0,
        description="with several cameras, a coasting track is reported while in the view of any camera that sent a "
                    "frame within this long")
    reorder_window_s: float = Field(default=0.5, ge=0.0, le=10.0,
                                    description="inputs older than this behind the newest are dropped")
    clock_jump_s: float = Field(
        default=5.0, gt=0.0, le=3600.0,
        description="a frame this much older than its source's newest is a clock jump (a replay that loops): "
                    "every track ends, its ID remembered, and tracking starts over; must exceed reorder_window_s")
    memory_path: Path | None = Field(default_factory=default_memory_path,
                                     description="ID memory file, loaded at start and rewritten on change; null: none")
    retention_s: float = Field(default=7 * 86400.0, gt=0.0,
                               description="a remembered ID not seen for this long is forgotten (s; default 7 days)")
    memory_save_period_s: float = Field(default=2.0, gt=0.0, le=3600.0,
                                        description="how often live tracks' galleries are also written")

    @model_validator(mode="before")
    @classmethod
    def _old_thesis_keys(cls, data: Any) -> Any:
        """Files written before the profiles had a section each: the thesis's keys at the top
        move under ``thesis:`` (a key given in both places is refused)."""
        if not isinstance(data, dict):
            return data
        old = [k for k in _OLD_THESIS_KEYS if k in data]
        if not old:
            return data
        data = dict(data)
        section = data.get("thesis") or {}
        if isinstance(section, ThesisConfig):
            section = section.model_dump(exclude_unset=True)
        if not isinstance(section, dict):
            return data  # the section's own validation says what is wrong with it
        twice = [k for k in old if k in section]
        if twice:
            raise ValueError(f"{', '.join(twice)} given both at the top and under 'thesis:'; the thesis profile's "
                             "settings belong under 'thesis:' only")
        log.warning("tracker settings %s at the top are the thesis profile's: write them under 'thesis:' "
                    "(e.g. thesis: {%s: ...}); read as such this time", ", ".join(old), old[0])
        data["thesis"] = {**section, **{k: data.pop(k) for k in old}}
        return data

    @model_validator(mode="after")
    def _clock_jump_beyond_window(self) -> TrackerConfig:
        if not self.clock_jump_s > self.reorder_window_s:
            raise ValueError(f"clock_jump_s ({self.clock_jump_s}) must exceed reorder_window_s "
                             f"({self.reorder_window_s}): a late frame within the window is reordered, not a clock jump")
        return self

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

    def appearance_model(self, thresholds: AppearanceConfig | None, metric: str | None = None) -> AppearanceModel | None:
        """The robust profile's view of a model's thresholds; ``metric`` from its model card."""
        if thresholds is None:
            return None
        chosen = thresholds.metric or metric or "euclidean"
        if chosen not in ("euclidean", "cosine"):
            raise ValueError(f"unknown descriptor metric {chosen!r}; the tracker knows euclidean and cosine")
        return AppearanceModel(thresholds.t_lower, thresholds.t_upper, thresholds.t_recover, chosen,  # type: ignore[arg-type]
                               thresholds.s_max)

    @property
    def profile_config(self) -> RobustConfig | ThesisConfig:
        """The settings section of the configured profile."""
        return {"robust": self.robust, "thesis": self.thesis}[self.profile]

    def score_models(self) -> dict[str, ScoreModel]:
        """The score models of the detectors that have their own (the robust profile's), by name."""
        return self.profile_config.score_models()

    def build_tracker(self, thresholds: AppearanceConfig | None, memory: IdentityMemory | None = None,
                      metric: str | None = None) -> TrackerCore:
        """The core tracker of the configured profile."""
        tracker = self.profile_config.build(self.appearance_model(thresholds, metric), memory, self.memory_size)
        tracker.memory.max_ids = self.max_remembered_ids
        return tracker

    def apply_thresholds(self, tracker: TrackerCore, thresholds: AppearanceConfig, metric: str | None = None) -> None:
        """Give ``tracker`` a model's thresholds (e.g. once its model card is known)."""
        tracker.set_appearance(self.appearance_model(thresholds, metric))

    @property
    def uses_detection_covariance(self) -> bool:
        return self.profile_config.use_detection_covariance
