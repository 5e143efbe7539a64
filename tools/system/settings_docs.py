"""The settings tables of the READMEs, generated from the settings models.

A README marks where a table goes::

    <!-- settings: services.detector.config:DetectorConfig -->
    (the generated table)
    <!-- /settings -->

and, optionally, a nested section after the model (``... :EmbedderConfig depth_mask``) for that
section's settings alone. ``python -m tools.system.settings_docs --write`` rewrites every marked
block from the code; ``--check`` rewrites nothing and exits 1 naming each README and block that
differs (tests/unit/test_settings_docs.py runs it).
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from pydantic import BaseModel

from common.runtime.settings import markdown_table

__all__ = ["Block", "SettingsDocError", "blocks", "check", "main", "readmes", "render", "write"]

ROOT = Path(__file__).resolve().parents[2]
FIX = "python -m tools.system.settings_docs --write"
_BLOCK = re.compile(r"(<!-- settings: (?P<spec>[^>]*?) -->\n)(?P<body>.*?)(<!-- /settings -->)", re.S)
_OPEN = re.compile(r"<!-- settings:")


class SettingsDocError(ValueError):
    """A marked block that cannot be generated: the message names the README, the block and the fix."""


@dataclass(frozen=True)
class Block:
    """One marked block: where it is, what it names and what it holds now."""

    readme: Path
    spec: str  #: ``module:Model`` and optionally a section, as written in the marker
    body: str


def readmes(root: Path = ROOT) -> list[Path]:
    """Every README.md under ``root``, outside hidden folders (the virtual environment's too)."""
    return sorted(p for p in root.rglob("README.md")
                  if not any(part.startswith(".") for part in p.relative_to(root).parts))


def blocks(readme: Path) -> list[Block]:
    """The marked blocks of ``readme``; SettingsDocError for a marker left open."""
    text = readme.read_text(encoding="utf-8")
    found = [Block(readme, m["spec"].strip(), m["body"]) for m in _BLOCK.finditer(text)]
    if len(_OPEN.findall(text)) != len(found):
        raise SettingsDocError(f"{readme}: a '<!-- settings: ... -->' marker has no '<!-- /settings -->' after it")
    return found


def _model(spec: str, where: str) -> tuple[type[BaseModel], str]:
    """The settings model and section a marker's ``module:Model [section]`` names."""
    target, _, section = spec.partition(" ")
    module_name, _, attr = target.partition(":")
    try:
        model = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError, ValueError) as exc:
        raise SettingsDocError(f"{where}: marker '{spec}' names no settings model ({exc}); "
                               "write it as 'package.module:ModelClass [section]'") from exc
    if not (isinstance(model, type) and issubclass(model, BaseModel)):
        raise SettingsDocError(f"{where}: marker '{spec}' names {model!r}, not a pydantic settings model")
    return model, section.strip()


def render(block: Block) -> str:
    """What ``block`` should hold: the generated table, with the blank lines around it."""
    model, section = _model(block.spec, str(block.readme))
    try:
        return "\n" + markdown_table(model, section) + "\n\n"
    except ValueError as exc:
        raise SettingsDocError(f"{block.readme}: marker '{block.spec}': {exc}") from exc


def _rewrite(readme: Path) -> tuple[str, str]:
    """``readme``'s text now and with every block generated."""
    text = readme.read_text(encoding="utf-8")
    blocks(readme)  # a marker left open fails here, naming the README

    def fill(m: re.Match[str]) -> str:
        return m.group(1) + render(Block(readme, m["spec"].strip(), m["body"])) + m.group(4)

    return text, _BLOCK.sub(fill, text)


def check(root: Path = ROOT) -> list[str]:
    """A line per marked block under ``root`` that differs from the code; [] when all agree."""
    stale = []
    for readme in readmes(root):
        for block in blocks(readme):
            if block.body != render(block):
                stale.append(f"{readme.relative_to(root)}: settings of {block.spec} differ from the code")
    return stale


def write(root: Path = ROOT) -> list[Path]:
    """Rewrite every marked block under ``root``; the READMEs that changed."""
    changed = []
    for readme in readmes(root):
        text, new = _rewrite(readme)
        if new != text:
            readme.write_text(new, encoding="utf-8")
            changed.append(readme)
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.system.settings_docs", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="rewrite every marked block from the settings models")
    mode.add_argument("--check", action="store_true", help="rewrite nothing; exit 1 if a block differs")
    parser.add_argument("--root", type=Path, default=ROOT, help="the repository (default: this checkout)")
    args = parser.parse_args(argv)
    try:
        if args.write:
            for readme in write(args.root):
                print(f"rewrote {readme.relative_to(args.root)}")
            return 0
        stale = check(args.root)
    except SettingsDocError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for line in stale:
        print(line, file=sys.stderr)
    if stale:
        print(f"run '{FIX}' to regenerate them", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
