"""TrackerConfig: the tracker's settings (services/tracker/README.md, *Settings*): each profile's
section, ``robust:`` and ``thesis:``, its defaults the core's (:class:`RobustParams`,
:class:`ThesisParams`), the service's and the ID memory's settings at the top. Appearance
thresholds depend on the embedding model's distance scale, so they live under the model's name in
``appearance`` (:data:`DEFAULT_APPEARANCE`: the shipped ones). The thesis's settings at the top (an
older file's ``n_init: 3``) still load: moved under ``thesis:``, with a warning naming the place.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any, Literal

from pydantic import ConfigDict, field_validator, model_validator

from common.runtime.settings import AdvancedBlock, setting

from services.tracker.core import AppearanceModel, ScoreModel, TrackerCore, ThesisParams
from services.tracker.core.identity import IdentityMemory
from services.tracker.profiles import ClassifierConfig, PostureConfig, RobustConfig, ScoreConfig, ThesisConfig

__all__ = ["DEFAULT_APPEARANCE", "DEFAULT_EMBEDDING_MODEL", "PROFILES", "AppearanceConfig",
           "ClassifierConfig", "PostureConfig", "RobustConfig", "ScoreConfig", "ThesisConfig", "TrackerConfig",
           "default_memory_path"]

log = logging.getLogger(__name__)

#: The tracker's profiles: ``robust`` (the default, built from Pinto's thesis, the TU Ilmenau
#: framework, Basso/Munaro and Ban et al.) and ``thesis`` (Pinto's thesis exactly, for
#: comparison and reproduction).
PROFILES = ("robust", "thesis")

#: The project's default embedder (services/embedder): an L2-normalised colour histogram.
DEFAULT_EMBEDDING_MODEL = "colour"


class AppearanceConfig(AdvancedBlock):
    """Algorithm 1 and 2 thresholds on one embedding model's distance scale."""

    model_config = ConfigDict(extra="forbid")

    t_lower: float = setting(..., "below this distance, appearance alone admits a pair", ge=0.0)
    t_upper: float = setting(..., "at or above this distance, the pair is never admitted", gt=0.0)
    t_recover: float = setting(..., "Algorithm 2: reuse a remembered ID closer than this", gt=0.0)
    s_max: float | None = setting(None, "per-model S_max (thesis profile); none: thesis.s_max", ge=0.0)
    metric: Literal["euclidean", "cosine"] | None = setting(
        None, "how the model's descriptors compare; none: as its model card says (euclidean if none)")

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
_D = ThesisParams()

#: The thesis profile's settings that used to sit at the top of the tracker's settings.
_OLD_THESIS_KEYS = tuple(ThesisConfig.model_fields)


class TrackerConfig(AdvancedBlock):
    """Everything ``perception tracker`` and ``perception track`` can be told."""

    model_config = ConfigDict(extra="forbid")

    profile: Literal["robust", "thesis"] = setting(
        "robust", "robust: cue fusion, staged association, life cycle in seconds; thesis: Pinto's thesis exactly "
                  "(--profile)")
    robust: RobustConfig = setting(description="the robust profile's settings", default_factory=RobustConfig)
    thesis: ThesisConfig = setting(description="the thesis profile's settings", default_factory=ThesisConfig)
    # --- appearance (both profiles) and the ID memory (Algorithm 2)
    embedding_model: str | None = setting(None, "accept descriptors of this model only (--embedding-model); none: the "
                                          "first model seen, or the memory file's", min_length=1, advanced=True)
    appearance: dict[str, AppearanceConfig] = setting(
        default_factory=_default_appearance, advanced=True,
        description="per embedding model, its t_lower, t_upper, t_recover and optional s_max and metric; a file's "
                    "models are added to (or override) the shipped ones")
    # --- bounded memory (the TU Ilmenau framework)
    memory_size: int = setting(_D.memory_size, "most descriptors kept per remembered ID", ge=1, le=100_000,
                               advanced=True)
    max_remembered_ids: int = setting(10_000, "most IDs remembered; one more forgets the one archived longest ago",
                                      ge=1, le=1_000_000, advanced=True)
    # --- service
    camera: str = setting("head", "camera whose localized and embeddings streams to track (--camera); '*' for all",
                          min_length=1)
    lasers: list[str] = setting(
        default_factory=lambda: ["front", "rear"],
        description="2-D lasers whose people (localized/{laser}, 'perception laser') the robust profile fuses with "
                    "the camera's, by position (--laser; none: the camera alone; the thesis profile reads none)")
    frame_id: str = setting("map", "tracking frame; inputs in another frame are dropped and counted", min_length=1)
    output_rate_hz: float = setting(10.0, "Tracks are published at this rate, predicted to the publish time (TU "
                                    "Ilmenau; --output-rate); 0: once per input frame", unit="Hz", ge=0.0, le=1000.0)
    join_wait_s: float = setting(0.1, "how long localized detections wait for their embeddings before they are "
                                 "tracked by position only", unit="s", ge=0.0, le=10.0, advanced=True)
    no_embeddings: list[str] = setting(
        default_factory=list, advanced=True,
        description="streams no embedder reads (a second, slow detector's, e.g. head-hog; --no-embeddings): their "
                    "frames are tracked by position at once, not after join_wait_s")
    view_age_s: float = setting(1.0, "with several cameras, a coasting track is reported while in the view of any "
                                "camera that sent a frame within this long", unit="s", gt=0.0, le=60.0, advanced=True)
    reorder_window_s: float = setting(0.5, "inputs older than this behind the newest are dropped (TU Ilmenau)",
                                      unit="s", ge=0.0, le=10.0, advanced=True)
    clock_jump_s: float = setting(
        5.0, "a frame this much older than its source's newest is a clock jump (a replay that loops): every track "
             "ends, its ID remembered, and tracking starts over; must exceed reorder_window_s", unit="s", gt=0.0,
        le=3600.0, advanced=True)
    memory_path: Path | None = setting(default_factory=default_memory_path,
                                       default_text="~/.local/state/people-perception/tracker-id-memory.npz",
                                       description="ID memory file, loaded at start and rewritten on change, so a "
                                                   "restarted tracker keeps identities (--memory); none: no memory "
                                                   "file (--no-memory)")
    retention_s: float = setting(7 * 86400.0, "a remembered ID not seen for this long is forgotten (7 days)",
                                 unit="s", gt=0.0)
    memory_save_period_s: float = setting(2.0, "how often the live tracks' galleries are also written", unit="s",
                                          gt=0.0, le=3600.0, advanced=True)

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

    @field_validator("lasers")
    @classmethod
    def _lasers(cls, v: list[str]) -> list[str]:
        for name in v:
            if not name or any(c in name for c in "/*$?# "):
                raise ValueError(f"laser {name!r} must be a name without '/', '*', '$', '?', '#' or spaces")
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
