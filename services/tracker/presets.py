"""The tracker's presets: named settings files under ``deploy/presets/`` (``several-cameras.yaml``,
``pets-site.yaml``...), each a layer of tracker settings between the defaults and
``--service-config`` (``perception tracker --preset NAME``, ``perception track --preset NAME``).
Each file starts with a comment saying where it fits and what it was measured on."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from common.runtime.config import ConfigError, read_config_file

__all__ = ["PRESETS_DIR", "PresetError", "load_preset", "preset_environment", "preset_names"]

#: Where the presets are: the repository's deploy/presets/.
PRESETS_DIR = Path(__file__).resolve().parents[2] / "deploy" / "presets"


class PresetError(ValueError):
    """An unknown or unreadable preset; the message names the known ones."""


def preset_names(folder: Path = PRESETS_DIR) -> list[str]:
    """The presets' names: the ``.yaml`` files of ``folder`` without the suffix, sorted."""
    return sorted(p.stem for p in folder.glob("*.yaml"))


def load_preset(name: str, folder: Path = PRESETS_DIR) -> dict[str, Any]:
    """The tracker settings of preset ``name`` (a mapping as in ``--service-config``'s ``tracker``
    section); :class:`PresetError` naming the known presets if there is none by that name."""
    path = folder / f"{name}.yaml"
    if "/" in name or not path.is_file():
        known = ", ".join(preset_names(folder)) or "none"
        raise PresetError(f"no tracker preset {name!r}; the presets: {known} (files in {folder})")
    try:
        return read_config_file(path)
    except ConfigError as exc:
        raise PresetError(f"tracker preset {name!r}: {exc}") from exc


def _flatten(tree: dict[str, Any], head: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for key, value in tree.items():
        name = f"{head}__{key.upper()}"
        if isinstance(value, dict):
            out.update(_flatten(value, name))
        else:
            out[name] = value if isinstance(value, str) else f"{value:g}" if isinstance(value, float) else str(value)
    return out


def preset_environment(name: str, folder: Path = PRESETS_DIR) -> dict[str, str]:
    """Preset ``name`` as ``PERCEPTION_TRACKER__...`` environment variables (its nested sections
    joined by ``__``), for tracker processes started with one environment for every service."""
    return _flatten(load_preset(name, folder), "PERCEPTION_TRACKER")
