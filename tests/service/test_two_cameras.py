"""Two cameras into one set of tracks (TU Ilmenau), the whole chain in process: the simulator's
head and back cameras, each with its own detector, localizer and embedder, one tracker. The
people of ``handover`` walk from in front of the robot to behind it and back."""

from __future__ import annotations

import logging

import pytest


@pytest.mark.slow
def test_the_back_camera_adds_the_people_behind_the_robot_to_the_same_tracks() -> None:
    """Over 20 s of ``handover``: with the back camera the ground truth counts about twice the
    people-frames (those behind the robot), and the fused tracks cover them at a MOTA no lower
    than the head camera alone on its own people (README: 42 s, 0.731 -> 0.824)."""
    from tools.demo.inprocess import run_chain

    logging.disable(logging.WARNING)
    try:
        head = run_chain("handover", duration_s=20.0).report["overall"]
        both = run_chain("handover", duration_s=20.0, back_camera="back").report["overall"]
    finally:
        logging.disable(logging.NOTSET)
    assert both["objects"] > 1.5 * head["objects"], (head["objects"], both["objects"])
    assert both["matches"] > 1.5 * head["matches"]
    assert both["mota"] >= head["mota"] - 0.02, (head["mota"], both["mota"])
    assert both["mota"] > 0.6
