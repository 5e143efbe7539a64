"""The tracker's code stays readable: no function longer than 50 lines or of cyclomatic
complexity above 15 (radon's count: each branch, loop, boolean operator and comprehension
clause), so a cue or a life-cycle rule reads as one short function."""

from __future__ import annotations

import ast
from pathlib import Path

from radon.complexity import cc_visit

ROOT = Path(__file__).resolve().parents[2]
TRACKER = ROOT / "services" / "tracker"
MAX_LINES = 50
MAX_COMPLEXITY = 15


def _sources() -> list[Path]:
    return sorted(p for p in TRACKER.rglob("*.py") if "__pycache__" not in p.parts)


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of every function of ``source`` longer than :data:`MAX_LINES`."""
    return [(n.name, n.end_lineno - n.lineno + 1) for n in ast.walk(ast.parse(source))
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno + 1 > MAX_LINES]


def complex_functions(source: str) -> list[tuple[str, int]]:
    """(name, complexity) of every function or method of ``source`` above :data:`MAX_COMPLEXITY`."""
    out = []
    for block in cc_visit(source):
        for b in [block, *getattr(block, "methods", [])]:
            if getattr(b, "is_method", None) is not None and b.complexity > MAX_COMPLEXITY:
                out.append((b.fullname, b.complexity))
    return out


def test_the_checks_see_a_long_and_a_tangled_function() -> None:
    tangled = "def f(x):\n" + "".join(f"    if x == {k} and x > 0:\n        return {k}\n" for k in range(9))
    assert complex_functions(tangled) == [("f", 19)]
    assert complex_functions("class C:\n    def m(self, x):\n        return x\n") == []
    assert long_functions("def g():\n" + "    x = 1\n" * 55) == [("g", 56)]


def test_no_tracker_function_is_long_or_tangled() -> None:
    found = []
    for path in _sources():
        text = path.read_text()
        where = path.relative_to(ROOT)
        found += [f"{where}: {name} has {n} lines (at most {MAX_LINES})" for name, n in long_functions(text)]
        found += [f"{where}: {name} has complexity {c} (at most {MAX_COMPLEXITY})" for name, c in complex_functions(text)]
    assert not found, "split these into functions that each do one thing:\n" + "\n".join(found)
