"""The test session keeps off the user's real state directory: ``tests/conftest.py`` points
``XDG_STATE_HOME`` at a temporary directory for this process and every child it starts, and the
tracker's default ID memory follows it."""

from __future__ import annotations

import os
from pathlib import Path

from services.tracker.config import TrackerConfig, default_memory_path
from tests.conftest import REAL_STATE_HOME, TEST_STATE_HOME
from tests.helpers.tracker_rig import KEYS, T0, Rig


def _listing(root: Path) -> set[str]:
    ours = root / "people-perception"
    return {str(p) for p in ours.rglob("*")} | ({str(ours)} if ours.exists() else set())


def test_the_state_directory_of_the_session_is_temporary() -> None:
    assert os.environ["XDG_STATE_HOME"] == str(TEST_STATE_HOME)
    assert Path(os.environ["XDG_STATE_HOME"]).resolve() != REAL_STATE_HOME.resolve()
    assert default_memory_path().is_relative_to(TEST_STATE_HOME)


def test_a_tracker_on_its_default_memory_writes_nothing_under_the_real_state_directory() -> None:
    before = _listing(REAL_STATE_HOME)
    config = TrackerConfig(output_rate_hz=0.0)  # memory_path: the default, as `perception tracker` has it
    assert config.memory_path is not None and config.memory_path.is_relative_to(TEST_STATE_HOME)
    rig = Rig(config)
    try:
        rig.walk(T0, 30, [(0, (2.0, 0.0, 0.0)), (1, (4.0, 1.0, 0.0))])
    finally:
        rig.service.close()  # writes the ID memory with the live tracks' galleries
    assert config.memory_path.is_file(), f"the tracker wrote no memory for {KEYS.robot} at {config.memory_path}"
    assert _listing(REAL_STATE_HOME) == before
    config.memory_path.unlink()
