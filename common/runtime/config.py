"""Layered, validated service configuration.

Order: model defaults (the papers' values) -> a YAML or JSON file -> environment
variables ``{PREFIX}__FIELD`` (``__`` separates nested fields, values parsed as YAML) ->
explicit overrides (CLI flags). pydantic validates the merged result once; a bad value
raises :class:`ConfigError` naming the field, the value and the constraint.
"""

from __future__ import annotations

import json
import re
import os
from pathlib import Path
from typing import Any, Mapping, Sequence, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from common.runtime.settings import unfold_advanced

__all__ = ["ConfigError", "format_validation_error", "key_line", "load_config", "read_config_file"]

C = TypeVar("C", bound=BaseModel)


class ConfigError(ValueError):
    """A configuration that cannot be used; the message says which value and why."""


def format_validation_error(exc: ValidationError, source: str = "", path: str | Path | None = None,
                            section: str | None = None) -> str:
    """One line per bad value (the field, why, what it got; with ``path``, the file's line that sets
    it, under ``section`` if given), after a line naming ``source``; a single bad value is one line."""
    lines = []
    for err in exc.errors(include_url=False):
        field = ".".join(str(p) for p in err["loc"]) or "(root)"
        value = err.get("input")
        shown = "" if isinstance(value, (dict, list)) or value is None else f" (got {value!r})"
        names = [*([section] if section else []), *(p for p in err["loc"] if isinstance(p, str))]
        line = key_line(path, names) if path is not None and names else None
        at = f", on line {line}" if line is not None else ""
        lines.append(f"{field}: {err['msg']}{shown}{at}")
    where = f" in {source}" if source else ""
    if len(lines) == 1:
        return f"invalid configuration{where}: {lines[0]}"
    return f"invalid configuration{where}:\n  " + "\n  ".join(lines)


def read_config_file(path: str | Path) -> dict[str, Any]:
    """A YAML (or JSON) mapping from ``path``; ConfigError if missing or malformed."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"config file {p} is a directory; give a YAML or JSON file")
    if not p.is_file():
        raise ConfigError(f"config file {p} does not exist")
    try:
        text = p.read_text()
        data = json.loads(text) if p.suffix == ".json" else yaml.safe_load(text)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f"config file {p} cannot be parsed: {exc}") from exc
    if not text.strip():
        raise ConfigError(f"config file {p} is empty; give a YAML or JSON mapping")
    if data is None:  # only comments
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"config file {p} must hold a mapping of settings, got {type(data).__name__}")
    return data


def key_line(path: str | Path, keys: Sequence[str]) -> int | None:
    """The line number of ``keys`` (a path of mapping keys, e.g. ``("tracker", "robust", "n_init")``)
    in a YAML/JSON file: each key searched from the line of the one before, for messages that name
    the line of a bad value; None when the last key is not found. A section the file does not
    spell (one the settings model filled in, e.g. from keys written at an older place) is passed over."""
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    found = None
    start = 0
    for i, key in enumerate(keys):
        pattern = re.compile(rf"""(^|[{{,\s])["']?{re.escape(key)}["']?\s*:""")
        found = next((n for n in range(start, len(lines)) if pattern.search(lines[n])), None)
        if found is None and i == len(keys) - 1:
            return None
        start = start if found is None else found
    return None if found is None else found + 1


def _merge(base: dict[str, Any], top: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in top.items():
        out[k] = _merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), dict) else v
    return out


def _from_env(prefix: str, environ: Mapping[str, str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    head = prefix.upper() + "__"
    for name, raw in environ.items():
        if not name.startswith(head):
            continue
        path = [p.lower() for p in name[len(head) :].split("__") if p]
        if not path:
            continue
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            value = raw
        node = out
        for p in path[:-1]:
            node = node.setdefault(p, {})
        node[path[-1]] = value
    return out


def load_config(model: type[C], path: str | Path | None = None, *, env_prefix: str | None = None,
                overrides: Mapping[str, Any] | None = None, section: str | None = None,
                environ: Mapping[str, str] | None = None, base: Mapping[str, Any] | None = None) -> C:
    """Build a validated ``model`` from defaults, file, environment and overrides.

    ``section`` names the part of the file for this service (e.g. ``tracker`` in a deploy
    file that configures several services): when the file has a top-level ``section``
    key, that mapping is used; otherwise the whole file holds this service's settings.
    ``overrides`` with value ``None`` are ignored, so unset CLI flags can be passed
    straight through. ``base`` (a preset) is a layer of settings under the file's.
    """
    data: dict[str, Any] = {}
    source = "defaults"
    in_section = None
    if path is not None:
        data = read_config_file(path)
        source = str(path)
        if section is not None and section in data:
            data = data[section] or {}
            source = f"{path}, section {section!r}"
            in_section = section
            if not isinstance(data, dict):
                raise ConfigError(f"section {section!r} of {path} must be a mapping")
    layers = [("a preset", dict(base or {})), (source, data)]
    if env_prefix:
        layers.append((f"the {env_prefix}* environment", _from_env(env_prefix, os.environ if environ is None else environ)))
    if overrides:
        layers.append(("the flags", {k: v for k, v in overrides.items() if v is not None}))
    data = {}
    for where, layer in layers:  # an advanced setting written under advanced: in one layer, beside it in another
        try:
            data = _merge(data, unfold_advanced(model, layer))
        except ValueError as exc:
            raise ConfigError(f"invalid configuration in {where}: {exc}") from exc
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(format_validation_error(exc, source, path, in_section)) from exc
