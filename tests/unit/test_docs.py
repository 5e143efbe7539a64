"""The top-level documents: the README's key table is the generated one, its command table names
every command, and every relative link in README.md, CHANGELOG.md and docs/*.md resolves."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from common.messages.keys import Keys
from perception.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def _slug(heading: str) -> str:
    """GitHub's anchor for a markdown heading's text."""
    text = heading.strip().lower().replace("`", "")
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return {_slug(m.group(1)) for m in re.finditer(r"^#{1,6} +(.+)$", text, flags=re.M)}


def test_readme_key_table_is_the_generated_one() -> None:
    table = Keys(robot="robot").markdown_table().strip()
    assert table in (ROOT / "README.md").read_text(encoding="utf-8")


def test_readme_command_table_names_every_command() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    rows = "\n".join(line for line in readme.splitlines() if line.startswith("| `perception "))
    missing = [c for c in COMMANDS if not re.search(rf"(`perception {c}\b|/ `{c}\b| `{c}`)", rows)]
    assert not missing, f"commands missing from the README's table: {missing}"


def test_readme_names_the_papers_not_seed_numbers() -> None:
    assert not re.search(r"seed 00\d", (ROOT / "README.md").read_text(encoding="utf-8"), flags=re.I)


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(doc: Path) -> None:
    broken = []
    for target in LINK.findall(doc.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+:", target):
            continue  # http(s), mailto
        path, _, anchor = target.partition("#")
        dest = (doc.parent / path).resolve() if path else doc
        if not dest.exists():
            broken.append(target)
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            broken.append(target)
    assert not broken, f"{doc.name}: links that lead nowhere: {broken}"
