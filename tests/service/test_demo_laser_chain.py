"""The in-process chain with the simulator's base laser: the laser node's people fused by the
tracker find more of the people around the robot than the camera alone, on the same ground truth."""

from __future__ import annotations

from tools.demo.inprocess import run_chain


def test_the_laser_finds_people_the_camera_cannot_see() -> None:
    alone = run_chain("still", duration_s=8.0, fps=15.0, laser=True, fuse_laser=False)
    fused = run_chain("still", duration_s=8.0, fps=15.0, laser=True)
    a, f = alone.report["sequences"]["still"], fused.report["sequences"]["still"]
    assert a["objects"] == f["objects"]  # the same ground truth: whom the camera or the laser could see
    assert f["misses"] < a["misses"]
    assert f["mota"] > a["mota"]
