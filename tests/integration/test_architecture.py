"""The architecture's rules (ARCHITECTURE.md), checked on the code itself.

* ``.importlinter``'s contracts: the layers perception > tools > services > common, no
  pipeline node importing another, algorithm cores free of transport, messages, config
  models and serialisation. Run with import-linter, the tool the contracts are written for.
* No import cycle between the project's modules, module level or inside functions.
* Every node's ``main.py`` stays a thin entry: description, flags, one ``run_node`` call.
* A command's module is named after it: ``main.py`` or ``<command>_cli.py``.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from common.messages.registry import NODES as REGISTRY

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("common", "services", "tools", "perception")
#: The pipeline nodes (services/), from the registry: attention included.
NODES = tuple(n.package.split(".")[1] for n in REGISTRY if n.package.startswith("services."))


def test_import_contracts_hold() -> None:
    # in a child process: import-linter reconfigures logging, which would silence the
    # loggers of the tests that run after this one
    code = ("import sys; from importlinter.cli import lint_imports; "
            f"sys.exit(lint_imports(config_filename={str(ROOT / '.importlinter')!r}, no_cache=True))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"an import contract is broken:\n{proc.stdout[-3000:]}{proc.stderr[-2000:]}"


def _strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's components with more than one module (the import cycles)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles() -> None:
    import grimp

    g = grimp.build_graph(*PACKAGES, cache_dir=None)
    # a package's __init__ importing its own submodules is not a cycle worth forbidding
    graph = {m: {i for i in g.find_modules_directly_imported_by(m) if not m.startswith(i + ".")} for m in g.modules}
    cycles = _strongly_connected(graph)
    assert cycles == [], f"import cycles: {cycles}"


@pytest.mark.parametrize("node", NODES)
def test_node_main_is_a_thin_entry(node: str) -> None:
    path = ROOT / "services" / node / "main.py"
    tree = ast.parse(path.read_text())
    code_lines = {n.lineno for n in ast.walk(tree) if isinstance(n, ast.stmt) and not (
        isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))}
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "run_node"]
    assert len(calls) == 1, f"{path} should hand its node to run_node"
    # the DESCRIPTION string is documentation; the code is imports, flags and one call
    assert len(code_lines) <= 15, f"{path} has {len(code_lines)} statements; move logic into the node or its flags"
    assert len(path.read_text().splitlines()) <= 40


def test_command_modules_are_named_after_their_commands() -> None:
    from perception.cli import COMMANDS

    modules = set()
    for command, (module, _) in COMMANDS.items():
        package, leaf = module.rsplit(".", 1)
        name = command.replace("-", "_").removesuffix("_" + package.rsplit(".", 1)[-1])
        assert leaf in ("main", f"{name}_cli"), f"perception {command} is {module}: name it {package}.{name}_cli"
        modules.add(module)
    named = {".".join(p.relative_to(ROOT).with_suffix("").parts) for package in ("common", "services", "tools")
             for p in (ROOT / package).rglob("*.py") if p.stem == "main" or p.stem.endswith("_cli")}
    assert named <= modules, f"named as a command's module, but no command runs it: {sorted(named - modules)}"


def test_the_tracker_core_reads_no_file_when_imported() -> None:
    # in a child process: the core imported fresh, with every way of opening a file refused
    code = ("import builtins, io, os, pathlib\n"
            "def refuse(*a, **k):\n    raise AssertionError(f'I/O at import: {a[:1]}')\n"
            "import numpy, scipy.optimize, scipy.linalg\n"  # their own start-up reads are theirs
            "builtins.open = io.open = os.open = refuse\n"
            "pathlib.Path.read_text = pathlib.Path.read_bytes = pathlib.Path.glob = refuse\n"
            "import services.tracker.core, services.tracker.core.cues\n"
            "print('ok')\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]
