"""The settings of Pinto's thesis profile (services/tracker/README.md, *How it works*, explains
them): the thesis's values by default."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Literal

from services.tracker.core.association import AppearanceGate

__all__ = ["ThesisParams"]

_F6 = tuple[float, float, float, float, float, float]
_F3 = tuple[float, float, float]
#: Algorithm 1's S_max when the embedding model names none (Pinto's thesis, eq. 17)
_S_MAX = next(f.default for f in fields(AppearanceGate) if f.name == "s_max")


@dataclass(frozen=True)
class ThesisParams:
    """Everything the core needs; defaults are the thesis's values (the README's *Settings*). Their
    ranges are checked where they are read, services/tracker/profiles.py's ThesisConfig (the only
    builder outside the tests)."""

    sigma0: _F6 = (0.2, 0.2, 0.2, 1.0, 1.0, 1.0)
    sigma_q: _F6 = (0.2, 0.2, 0.2, 1.0, 1.0, 1.0)
    sigma_r: _F3 = (0.2, 0.2, 0.2)
    gate: AppearanceGate | None = None
    t_recover: float = 400.0
    n_init: int = 3
    max_misses: int = 5
    time_step: Literal["time", "frame"] = "time"
    frame_period_s: float = 1.0 / 30.0
    gallery_size: int = 500
    memory_size: int = 500
    position_gate_probability: float = 0.95
    inf: float = 1e5
    #: S_max of the gate :meth:`ThesisTracker.set_appearance` builds for a model that names none
    s_max: float = _S_MAX
