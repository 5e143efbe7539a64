"""What the installed distribution holds: modules that import with the runtime dependencies
alone, and no test fixtures.

``pip install -e .`` without ``[test]`` has no ``onnx``, ``pytest`` or ``hypothesis``, and
``tests/`` is not installed. Every module of the installed packages must import there; the
subprocess below blocks those modules before importing anything, so a stray import of a
test-only package (or of ``tests.fixtures``) fails here rather than on a robot.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("services", "common", "tools", "perception")
#: Importable in a test environment, absent from a runtime install.
TEST_ONLY = ("onnx", "pytest", "hypothesis", "_pytest", "tests")
#: File names of test data builders, which belong in tests/fixtures/.
FIXTURE_NAMES = {"synthetic.py", "testing.py", "scene.py", "fixtures.py", "conftest.py"}

_IMPORT_ALL = r"""
import importlib, importlib.abc, json, pkgutil, sys, traceback

BLOCKED = set(sys.argv[1].split(","))

class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r} (test-only, blocked)", name=name)
        return None

sys.meta_path.insert(0, Block())
failed, names = {}, []

def record(name):
    failed[name] = traceback.format_exc(limit=-3)

for package in sys.argv[2].split(","):
    try:
        pkg = importlib.import_module(package)
    except Exception:
        record(package)
        continue
    names.append(package)
    for info in pkgutil.walk_packages(pkg.__path__, package + ".", onerror=record):
        if info.name.rsplit(".", 1)[-1] == "__main__":
            continue  # runs the command
        names.append(info.name)
        try:
            importlib.import_module(info.name)
        except Exception:
            record(info.name)
leaked = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
print(json.dumps({"imported": names, "failed": failed, "leaked": leaked}))
"""


def test_every_module_imports_without_test_only_packages() -> None:
    res = subprocess.run(
        [sys.executable, "-c", _IMPORT_ALL, ",".join(TEST_ONLY), ",".join(PACKAGES)],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert not out["failed"], "\n\n".join(f"{name}:\n{tb}" for name, tb in out["failed"].items())
    assert not out["leaked"]
    imported = set(out["imported"])
    # the walk really went everywhere: every module file on disk was imported
    on_disk = {
        ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        for package in PACKAGES
        for p in (ROOT / package).rglob("*.py")
        if "__pycache__" not in p.parts and p.stem != "__main__"
    }
    assert on_disk <= imported, f"not reached by pkgutil: {sorted(on_disk - imported)}"
    for name in ("services.detector.service", "tools.simulator.core.render", "perception.cli", "common.runtime.node"):
        assert name in imported


def test_no_fixture_ships_in_the_packages() -> None:
    for package in PACKAGES:
        for p in (ROOT / package).rglob("*.py"):
            rel = p.relative_to(ROOT)
            assert p.name not in FIXTURE_NAMES, f"{rel} looks like test data; it belongs in tests/fixtures/"
            assert not rel.parts[-1].startswith("test_"), f"{rel} is a test; it belongs in tests/"
            # a folder of modules without __init__.py is left out of the wheel by setuptools' find
            if "__pycache__" not in p.parts:
                assert (p.parent / "__init__.py").is_file(), f"{rel.parent} has modules but no __init__.py"


def test_fixtures_are_a_test_package() -> None:
    fixtures = ROOT / "tests" / "fixtures"
    assert (fixtures / "__init__.py").is_file()
    assert {p.name for p in fixtures.glob("*.py")} >= {
        "detector_synthetic.py",
        "embedder_synthetic.py",
        "embedder_onnx_models.py",
        "localizer_synthetic.py",
        "localizer_scene.py",
        "replay_bags.py",
    }
