"""The test suite's own rules (tests/README.md): every test module sits in a tier, no module
imports a test module (shared rigs live in tests/helpers/ and tests/fixtures/), and the
lower tiers start no process and open no real Zenoh session."""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
TIERS = ("unit", "service", "integration")

#: Imports that make a module integration: child processes, a real router or Zenoh session,
#: and the helpers that start them.
INTEGRATION_IMPORTS = ("subprocess", "multiprocessing", "common.transport.router_process", "common.transport.zenoh",
                       "tests.helpers.chromium", "tests.helpers.launcher", "tests.helpers.recording",
                       "tests.helpers.scored_launch")
#: conftest.py's fixtures that start a router.
INTEGRATION_FIXTURES = {"router", "zenoh_client"}
#: Imports that make a module service at least: the in-memory transport and the rigs on it.
SERVICE_IMPORTS = ("common.transport.memory", "tests.helpers.embedder_rig", "tests.helpers.tracker_rig", "tools.demo.inprocess")
SERVICE_FIXTURES = {"memory_bus"}


def _is_test_module(path: Path) -> bool:
    return path.name.startswith("test_") or path.name.endswith("_test.py")  # pytest's default python_files


def _sources() -> list[Path]:
    return sorted(p for p in TESTS.rglob("*.py") if "__pycache__" not in p.parts)


def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), str(path))


def _imports(path: Path) -> set[str]:
    """The dotted names a module imports anywhere in it, relative imports made absolute."""
    package = path.relative_to(TESTS.parent).with_suffix("").parts[:-1]
    names: set[str] = set()
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = [*package[: len(package) - node.level + 1]] if node.level else []
            module = ".".join([*base, *([node.module] if node.module else [])])
            names.add(module)
            names.update(f"{module}.{a.name}" for a in node.names)
    return names


def _outermost(names: set[str]) -> list[str]:
    """``names`` without those inside another of them (``a.b`` goes when ``a`` is there)."""
    return sorted(n for n in names if not any(n.startswith(m + ".") for m in names))


def _uses(names: set[str], prefixes: tuple[str, ...]) -> list[str]:
    return _outermost({n for n in names if any(n == p or n.startswith(p + ".") for p in prefixes)})


def _fixtures(path: Path) -> set[str]:
    """The parameter names of the module's functions (the fixtures its tests and fixtures ask for)."""
    return {a.arg for node in ast.walk(_tree(path)) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            for a in node.args.args}


def _marked_zenoh(path: Path) -> bool:
    """Whether the module uses ``pytest.mark.zenoh`` (a real router)."""
    return any(isinstance(node, ast.Attribute) and node.attr == "zenoh" and isinstance(node.value, ast.Attribute)
               and node.value.attr == "mark" for node in ast.walk(_tree(path)))


def test_every_test_module_sits_in_a_tier() -> None:
    misplaced = [str(p.relative_to(TESTS)) for p in _sources()
                 if _is_test_module(p) and not (p.parent.parent == TESTS and p.parent.name in TIERS)]
    assert not misplaced, f"test modules outside tests/{{{','.join(TIERS)}}}/ (see tests/README.md): {misplaced}"


def test_no_module_imports_a_test_module() -> None:
    stems = {p.stem for p in _sources() if _is_test_module(p)}
    offences = [f"{p.relative_to(TESTS)} imports {name}" for p in _sources()
                for name in _outermost({n for n in _imports(p) if stems & set(n.split("."))})]
    assert not offences, "move what they share to tests/helpers/ or tests/fixtures/:\n" + "\n".join(offences)


def test_the_lower_tiers_start_no_process_and_no_router() -> None:
    offences = []
    for tier in ("unit", "service"):
        for p in sorted((TESTS / tier).glob("*.py")):
            names, fixtures, rel = _imports(p), _fixtures(p), p.relative_to(TESTS)
            offences += [f"{rel} imports {n}" for n in _uses(names, INTEGRATION_IMPORTS)]
            offences += [f"{rel} uses the {f} fixture" for f in sorted(fixtures & INTEGRATION_FIXTURES)]
            if _marked_zenoh(p):
                offences.append(f"{rel} is marked zenoh")
            if tier == "unit":
                offences += [f"{rel} imports {n} (in-memory transport: service)" for n in _uses(names, SERVICE_IMPORTS)]
                offences += [f"{rel} uses the {f} fixture (service)" for f in sorted(fixtures & SERVICE_FIXTURES)]
    assert not offences, "these belong to a higher tier (tests/README.md):\n" + "\n".join(offences)
