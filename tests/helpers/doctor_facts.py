"""The doctor's facts of a healthy run (the simulated apartment through the four nodes, 3 s at 8 fps),
for the doctor's offline tests to break one fact at a time."""

from __future__ import annotations

import numpy as np

from tools.doctor.core.facts import EdgeFacts, FrameFacts, NodeFacts, Observation, StreamFacts

__all__ = ["INPUTS", "K", "N", "OUTPUTS", "S", "SETTINGS", "T0", "healthy"]

S = 1_000_000_000
T0 = 1_700_000_000 * S
N = 24  # frames in the 3 s watched, at 8 fps
K = np.array([[262.5, 0, 159.5], [0, 262.5, 119.5], [0, 0, 1.0]])
INPUTS = {"detector": ["frames/head"], "localizer": ["tf_static", "tf", "frames/head", "detections/head"],
          "embedder": ["frames/head", "detections/head"], "tracker": ["localized/head", "embeddings/head"]}
OUTPUTS = {"detector": "detections/head", "localizer": "localized/head", "embedder": "embeddings/head",
           "tracker": "tracks"}
SETTINGS = {
    "detector": {"backend": "depth", "camera": "head"},
    "localizer": {"camera": "head", "target_frame": "map", "camera_frame": "", "static_transforms": ""},
    "embedder": {"backend": "colour", "camera": "head"},
    "tracker": {"profile": "robust", "camera": "head", "frame_id": "map", "appearance": "colour,trinet"},
}


def _key(i: int) -> tuple[int, str, int]:
    return (T0 + i * S // 8, "head", i)


def healthy() -> Observation:
    """What the doctor sees of the simulated apartment through the four nodes, 3 s at 8 fps."""
    end = T0 + 3 * S
    streams = {k: StreamFacts(k, count=N, first_ns=T0, last_ns=end) for k in
               ("frames/head", "detections/head", "localized/head", "embeddings/head", "tracks", "tf")}
    streams["tf_static"] = StreamFacts("tf_static", count=3, first_ns=T0, last_ns=end)
    nodes = [NodeFacts(s, f"pc-{i}", host="pc", uptime_s=10.0, window_s=3.0, settings=dict(SETTINGS[s]),
                       subscribes=INPUTS[s], publishes=[OUTPUTS[s]], counters={"received": N, "published": N})
             for i, s in enumerate(INPUTS)]
    rng = np.random.default_rng(0)
    frames = [FrameFacts("head", T0 + i * S // 2, T0 + i * S // 2 + 25_000_000, "camera", (240, 320), (240, 320),
                         "16UC1", rng.uniform(1500, 6000, 500), (240, 320), K.copy()) for i in range(6)]
    edges = [EdgeFacts("map", "odom", False, N, T0, end), EdgeFacts("odom", "base_link", False, N, T0, end),
             EdgeFacts("base_link", "head_link", True, 3, T0, T0), EdgeFacts("head_link", "camera", True, 3, T0, T0)]
    keys = {_key(i): T0 + i * S // 8 + 30_000_000 for i in range(N)}
    stages = {"head": {s: dict(keys) for s in ("frames", "detections", "localized", "embeddings", "tracks")}}
    return Observation(duration_s=3.0, end_ns=end, streams=streams, nodes=nodes, frames={"head": frames},
                       offsets_ns={"head": [25_000_000] * N}, edges=edges, stages=stages,
                       cards=[("colour", 128, "euclidean", True)], track_models=["colour"], track_frames=["map"],
                       localized_frames=["map"], tracks_total=N, boxes_total=30)
