"""Quality gate: on the KITTI pedestrians dev split (score >= 2.683) the tracker keeps its MOTA.

The trackers, the loading and the judging are benchmarks/quality.py's (imported by path),
so the gate measures exactly what the benchmark prints. Needs ../shared/data (or
$PERCEPTION_SHARED_DATA); skipped without it.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest


#: MOTA floors, per what is judged: the robust profile measures 0.550 here (commit 2437733),
#: the pre-profile defaults measured 0.480 (the thesis profile still does). Each floor is the
#: measured figure minus a small margin; raise it when the tracker improves.
MOTA_FLOOR = {"robust": 0.54, "default": 0.47}


def _quality() -> ModuleType:
    from benchmarks import quality

    return quality


@pytest.fixture(scope="module")
def quality() -> ModuleType:
    return _quality()


@pytest.fixture
def kitti(shared_data: Path, quality: ModuleType) -> list:
    root = shared_data / "kitti_ped_dev"
    if not root.is_dir():
        pytest.skip(f"KITTI pedestrians dev split not found at {root}")
    return quality.load_kitti(root, min_score=quality.KITTI_SCORE_CUT)


def _ours(quality: ModuleType):
    """The robust profile when TrackerConfig has profiles, else the defaults."""
    configs = dict(quality.project_configs())
    label = "robust" if "robust" in configs else "default"
    return quality.project_adapter(label, configs[label])


def test_tracker_keeps_mota_floor_on_kitti(quality: ModuleType, kitti: list) -> None:
    ours = _ours(quality)
    result = quality.score(ours, kitti).result
    assert result.objects == 1309  # the whole dev split was judged
    floor = MOTA_FLOOR[ours.name]
    assert result.mota >= floor, f"{ours.name}: MOTA {result.mota:.3f} fell below the floor {floor}"


def test_robust_profile_beats_the_kalman_baseline_on_kitti(quality: ModuleType, kitti: list) -> None:
    # Active only when TrackerConfig has `profile`: the pre-profile defaults (MOTA 0.480, as
    # the thesis profile today) are below the 50-line constant-velocity Kalman baseline
    # (0.503), which the robust profile exists to fix. The baseline is computed here, in the
    # same run, on the same data and judging.
    if not quality.has_profiles():
        pytest.skip("TrackerConfig has no 'profile' yet; the robust profile must beat the baseline once it lands")
    ours = quality.score(_ours(quality), kitti).result
    baseline = quality.score(quality.TrackerAdapter("kalman-baseline", quality.run_kalman_baseline), kitti).result
    assert ours.mota > baseline.mota, f"robust MOTA {ours.mota:.3f} is not above the Kalman baseline's {baseline.mota:.3f}"
