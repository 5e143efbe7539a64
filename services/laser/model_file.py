"""The leg classifier's file: JSON, written by ``perception train-legs``, read by the laser node
and ``perception legs``. The shipped one is :data:`DEFAULT_MODEL`, trained on the dev scans
named inside it (their sha256); the same command rebuilds it to the byte."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from services.laser.core.boost import Boosted
from services.laser.core.features import MODEL

__all__ = ["DEFAULT_MODEL", "ModelFileError", "load_model", "write_model"]

DEFAULT_MODEL = Path(__file__).resolve().parent / "legs_model.json"
FORMAT = "people-perception leg classifier"
VERSION = 1


class ModelFileError(ValueError):
    """A leg model file that cannot be used; the message names the file and the fix."""


def write_model(path: Path, model: Boosted, meta: dict[str, Any]) -> None:
    doc = {"format": FORMAT, "version": VERSION, "meta": meta, "model": model.to_json()}
    Path(path).write_text(json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")


def load_model(path: Path | None = None) -> tuple[Boosted, dict[str, Any]]:
    """The classifier in ``path`` (default: the shipped one) and its training record."""
    path = Path(path) if path is not None else DEFAULT_MODEL
    fix = "give --model a file written by 'perception train-legs', or leave it out for the shipped model"
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise ModelFileError(f"leg model {path} does not exist: {fix}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"leg model {path} is not readable JSON ({exc}): {fix}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ModelFileError(f"{path} is not a leg model (no format {FORMAT!r}): {fix}")
    if doc.get("version") != VERSION:
        raise ModelFileError(f"leg model {path} has version {doc.get('version')}, this code reads {VERSION}: {fix}")
    meta = doc.get("meta") or {}
    names = meta.get("features")
    if names != list(MODEL):
        raise ModelFileError(f"leg model {path} was trained on other features ({names}); retrain it with "
                             "'perception train-legs'")
    try:
        model = Boosted.from_json(doc["model"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelFileError(f"leg model {path} is damaged ({exc}): {fix}") from None
    if model.feature.size and (model.feature.min() < 0 or model.feature.max() >= len(MODEL)):
        raise ModelFileError(f"leg model {path} names a feature outside 0..{len(MODEL) - 1}: {fix}")
    return model, meta
