"""Real video through the live services: PETS09-S2L1's first 100 frames played by perception camera
(--max) through the HOG detector, the localizer on the floor homography (no depth), the colour
embedder and the tracker, as processes over a real router, scored against the ground truth; the
same frames through benchmarks/quality.py's offline chain, with the tracker run as there. The two
agree within 0.02 MOTA and IDF1. All 400 frames: python benchmarks/pets_live.py."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]
FRAMES = 100


def _pets_live() -> ModuleType:
    from benchmarks import pets_live

    return pets_live


def test_pets09_through_the_live_services_matches_the_offline_chain(shared_data: Path, tmp_path: Path) -> None:
    pets = shared_data / "pets09_dev"
    if not pets.is_dir():
        pytest.skip(f"{pets} is absent")
    live_mod = _pets_live()
    live = live_mod.run_live(pets, FRAMES, tmp_path, env=live_mod.LIKE_OFFLINE)
    assert live.frames == FRAMES, live.log
    offline = live_mod.run_offline(pets, FRAMES, None)
    got, want = live_mod.judge(pets, FRAMES, live.rows), live_mod.judge(pets, FRAMES, offline)
    summary = {"live": (got.mota, got.idf1, got.id_switches), "offline": (want.mota, want.idf1, want.id_switches)}
    assert want.mota > 0.6, summary
    assert abs(got.mota - want.mota) <= 0.02 and abs(got.idf1 - want.idf1) <= 0.02, summary
