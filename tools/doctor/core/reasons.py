"""What each counted drop reason means and how to fix it, one line each.

The names are the nodes' ``dropped_<reason>`` counters (their READMEs list them).
"""

from __future__ import annotations

__all__ = ["REASON_FIX", "reason_fix"]

REASON_FIX: dict[str, str] = {
    # detector
    "bad_image": "the colour image cannot be decoded: check the driver's encoding (rgb8, bgr8, mono8, jpeg, png)",
    "no_depth": "the depth detector needs depth in every frame: enable the camera's depth stream",
    "detector_error": "the detector's model failed on a frame: see the detector's log",
    # localizer
    "no_transform": "the transform from the camera to the map is missing at the frames' stamps: see the Transforms lines",
    "no_depth_frame": "the depth frame of the detections never arrived or was evicted: raise the localizer's "
                      "frame_buffer, or check the frames' rate",
    "frame_without_depth": "the frames carry no depth image and the localizer's floor_without_depth is off: enable "
                           "the camera's depth stream, or turn floor_without_depth on to put people on the floor",
    "size_mismatch": "detections are for another image size than the depth (or, without depth, the camera info): "
                     "register depth to the colour image",
    "homography_size_mismatch": "the frames have another aspect ratio than the floor homography's image_size: fit "
                                "the homography on this camera's images",
    "bad_depth": "the depth image cannot be decoded: send 16UC1 millimetres or 32FC1 metres",
    "no_camera_frame": "the frames name no frame_id: set the driver's frame id or the localizer's camera_frame",
    "pending_overflow": "too many detections wait for depth or transforms: a stage is far behind",
    # embedder
    "stale": "the embedder falls behind the camera (max_lag_s): use a faster backend or a lower frame rate",
    "unpaired": "the colour frame of the detections was gone: raise the embedder's frame_buffer",
    "backend_error": "the embedding model failed on a frame: see the embedder's log",
    # tracker
    "wrong_model": "the tracker takes descriptors of another embedding model: see the Config lines",
    "wrong_dimension": "descriptors of another dimension than the tracker's ID memory: move the memory file away "
                       "or use the same model",
    "late_embeddings": "embeddings arrive after the tracker stopped waiting: raise the tracker's join_wait_s or "
                       "speed up the embedder",
    "unpaired_embeddings": "embeddings whose localized detections never came: see the localizer's drops",
    "wrong_frame": "localized detections in another frame than the tracker's frame_id: make the localizer's "
                   "target_frame and the tracker's frame_id the same",
    "too_old": "frames older than the tracker's reorder window: a stage lags, or stamps jump",
    "join_overflow": "too many frames wait for their embeddings: the embedder is far behind",
    # any joiner
    "duplicate": "the same frame arrives twice: two publishers on one camera, or a replay that loops",
}


def reason_fix(reason: str, node: str) -> str:
    """The one-line fix for ``node``'s drop ``reason``."""
    return REASON_FIX.get(reason, f"see the {node}'s log, which names each {reason} drop")
