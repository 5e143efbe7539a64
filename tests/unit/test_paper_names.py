"""The papers are named by their authors (Pinto's thesis, the TU Ilmenau framework,
Basso/Munaro, Ban et al.), never by number: "seed 001" reads like the random seed that
``perception demo --seed`` and ``perception simulate --seed`` take."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from perception.cli import COMMANDS, main

ROOT = Path(__file__).resolve().parents[2]

#: A paper called by number ("seed 002", "seeds 000", "seed-003", "seed001_x") or all of them
#: at once ("all four seeds").
BY_NUMBER = re.compile(r"seeds?[\s_-]*00[0-3]|\bfour\s+seeds\b", re.IGNORECASE)
SEED = re.compile(r"\bseeds?\b", re.IGNORECASE)
#: The flag and its metavar as the usage line spells them.
SEED_FLAG = re.compile(r"--seed(?:[ =][A-Z_]+)?")
#: Where the papers could be named: the code, its tests, benchmarks and deploy files.
SCANNED = ("common", "services", "tools", "perception", "benchmarks", "tests", "deploy", "scripts",
           "ARCHITECTURE.md")


def seed_mentions(help_text: str) -> list[str]:
    """The lines of ``help_text`` that say "seed" other than about a random seed.

    Allowed: the flag ``--seed`` in the usage line, the line of its own description when that
    says "random", and the settings list's ``seed = ...`` line when the description under it
    says "random". ``help_text`` must be formatted wide enough for one line per option."""
    bad = []
    lines = help_text.splitlines()
    for k, line in enumerate(lines):
        stripped = line.strip()
        described = "random" in line or (stripped.startswith("seed =") and "random" in "".join(lines[k + 1:k + 2]))
        if BY_NUMBER.search(line):
            bad.append(stripped)
        elif stripped.startswith("--seed"):
            if "random" not in line:
                bad.append(stripped)
        elif stripped.startswith("seed =") and described:
            continue
        elif SEED.search(SEED_FLAG.sub("", line) if stripped.startswith("usage:") else line):
            if "random" not in line:
                bad.append(stripped)
    return bad


def test_the_check_flags_papers_by_number_and_seeds_that_are_not_random() -> None:
    assert seed_mentions("usage: perception demo [-h] [--seed SEED]\n"
                         "  --seed SEED   random seed (default 0): same seed, same run") == []
    assert seed_mentions("Profile 'robust' fuses the cues of all four seeds and") != []
    assert seed_mentions("  --profile     'thesis': seed 000 exactly") != []
    assert seed_mentions("settings:\n  seed = 0; >= 0\n      random seed: same seed, same run") == []
    assert seed_mentions("settings:\n  seed = 0; >= 0\n      the paper's scenario") != []
    assert seed_mentions("  --seed SEED   scenario seed (default 0)") != []
    assert seed_mentions("  --seed SEED   random seed, as seed 001 did") != []


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_help_says_seed_only_of_a_random_seed(command: str, monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("COLUMNS", "1000")  # argparse's width: each option's help on one line
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert f"usage: perception {command}" in out
    assert seed_mentions(out) == []


def test_no_paper_is_called_by_number_in_the_tree() -> None:
    hits = []
    for name in SCANNED:
        top = ROOT / name
        paths = [top] if top.is_file() else sorted(p for p in top.rglob("*") if p.is_file())
        for path in paths:
            if path == Path(__file__).resolve() or "__pycache__" in path.parts:
                continue  # this file spells the old names to test the check
            try:
                text = path.read_text(encoding="utf-8")
            except UnicodeDecodeError:
                continue
            for n, line in enumerate(text.splitlines(), 1):
                if BY_NUMBER.search(line):
                    hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert hits == [], "name the paper (Pinto's thesis, the TU Ilmenau framework, Basso/Munaro, " \
                       "Ban et al.):\n" + "\n".join(hits)
