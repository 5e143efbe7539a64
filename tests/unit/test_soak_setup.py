"""benchmarks/soak.py starts what `perception demo` starts, from the demo's own defaults: this
guards that coupling without running the hour-long benchmark."""

from __future__ import annotations

import argparse
from pathlib import Path

from tools.demo.main import _specs
from tools.demo.main import add_arguments as add_demo_arguments


def test_the_demo_defaults_build_the_soak_processes(tmp_path: Path) -> None:
    parser = argparse.ArgumentParser()
    add_demo_arguments(parser)
    specs = _specs("tcp/127.0.0.1:7999", 7999, "soak1", parser.parse_args([]), tmp_path / "ids.npz")
    names = [s.name for s in specs]
    assert names == ["router", "detector", "localizer", "embedder", "tracker"]
    tracker = specs[-1].argv
    assert "--output-rate" in tracker and tracker[tracker.index("--output-rate") + 1] == "0"
