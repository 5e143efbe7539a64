"""Hypothesis strategies producing valid instances of every message schema."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from common.messages.schemas import (
    AppearanceThresholds,
    CameraInfo,
    CameraView,
    Detection,
    Detections,
    AttentionReply,
    Embeddings,
    ForgetReply,
    HeadCommand,
    Header,
    Image,
    LocalizedDetection,
    LocalizedDetections,
    ModelCard,
    PeopleGroundTruth,
    PersonGroundTruth,
    RGBDFrame,
    ServiceStatus,
    TrackState,
    Tracks,
    Transform,
    TransformBatch,
)

names = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=1, max_size=12)
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
stamps = st.integers(0, 2**63 - 1)


def vec(n: int) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.float64, (n,), elements=finite)


headers = st.builds(Header, stamp_ns=stamps, frame_id=st.text(max_size=10), seq=st.integers(0, 2**40),
                    source=st.text(max_size=10))


@st.composite
def images(draw: st.DrawFn, kinds: tuple[str, ...] = ("rgb8", "bgr8", "mono8", "16UC1", "32FC1", "png")) -> Image:
    enc = draw(st.sampled_from(kinds))
    h, w = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    if enc in ("rgb8", "bgr8"):
        arr = draw(hnp.arrays(np.uint8, (h, w, 3)))
    elif enc == "mono8":
        arr = draw(hnp.arrays(np.uint8, (h, w)))
    elif enc in ("16UC1", "png"):
        arr = draw(hnp.arrays(np.uint16, (h, w)))
    else:
        arr = draw(hnp.arrays(np.float32, (h, w), elements=st.floats(0, 20, width=32) | st.just(float("nan"))))
    return Image.from_array(arr, enc, draw(headers))  # type: ignore[arg-type]


@st.composite
def camera_infos(draw: st.DrawFn, width: int | None = None, height: int | None = None) -> CameraInfo:
    w = width or draw(st.integers(1, 4096))
    h = height or draw(st.integers(1, 4096))
    fx, fy = draw(st.floats(1, 5000)), draw(st.floats(1, 5000))
    k = np.array([[fx, 0, draw(st.floats(0, w))], [0, fy, draw(st.floats(0, h))], [0, 0, 1]])
    model = draw(st.sampled_from(["plumb_bob", "rational_polynomial", "equidistant", "none"]))
    n = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4, "none": 0}[model]
    return CameraInfo(header=draw(headers), width=w, height=h, K=k, D=draw(vec(n)), distortion_model=model)


@st.composite
def rgbd_frames(draw: st.DrawFn) -> RGBDFrame:
    rgb = draw(images(("rgb8", "bgr8", "mono8")))
    depth_enc = draw(st.sampled_from(["16UC1", "32FC1", None]))
    depth = None
    if depth_enc == "16UC1":
        depth = Image.from_array(draw(hnp.arrays(np.uint16, rgb.shape[:2])), "16UC1", rgb.header)
    elif depth_enc == "32FC1":
        depth = Image.from_array(draw(hnp.arrays(np.float32, rgb.shape[:2], elements=st.floats(0, 10, width=32))), "32FC1", rgb.header)
    cam = draw(camera_infos(rgb.width, rgb.height))
    return RGBDFrame(header=rgb.header, rgb=rgb, depth=depth, camera_info=cam)


@st.composite
def quaternions(draw: st.DrawFn) -> np.ndarray:
    q = draw(hnp.arrays(np.float64, (4,), elements=st.floats(-1, 1)))
    if np.linalg.norm(q) < 0.1:
        q = np.array([0.0, 0.0, 0.0, 1.0])
    return q / np.linalg.norm(q)


transforms = st.builds(
    Transform,
    parent_frame=st.sampled_from(["map", "odom"]),
    child_frame=st.sampled_from(["base_link", "camera"]),
    stamp_ns=stamps,
    translation=vec(3),
    rotation_xyzw=quaternions(),
    static=st.booleans(),
)
transform_batches = st.builds(TransformBatch, header=headers, transforms=st.lists(transforms, max_size=4))

boxes = st.tuples(finite, finite, finite, finite)
scores = st.floats(0, 1)
detections_msgs = st.builds(
    Detections,
    header=headers,
    detections=st.lists(st.builds(Detection, index=st.integers(0, 1000), bbox_xyxy=boxes, score=scores,
                                  class_id=st.integers(0, 100), class_name=st.text(max_size=8)), max_size=5),
    image_width=st.integers(0, 4096),
    image_height=st.integers(0, 4096),
    detector=st.text(max_size=8),
    inference_ms=st.none() | st.floats(0, 1e4),
)
localized_msgs = st.builds(
    LocalizedDetections,
    header=headers,
    camera_frame=st.text(max_size=8),
    detections=st.lists(
        st.builds(LocalizedDetection, index=st.integers(0, 1000), bbox_xyxy=boxes, score=scores, position=vec(3),
                  cov=hnp.arrays(np.float64, (3, 3), elements=finite), depth_m=st.floats(0.01, 20),
                  valid_pixels=st.integers(0, 10**6)),
        max_size=5,
    ),
    rejected=st.dictionaries(st.text(max_size=8), st.integers(0, 100), max_size=3),
    view=st.none() | st.builds(CameraView, camera_to_frame=hnp.arrays(np.float64, (4, 4), elements=finite),
                               K=hnp.arrays(np.float64, (3, 3), elements=finite), width=st.integers(1, 4096),
                               height=st.integers(1, 4096), max_range_m=st.floats(0.1, 100)),
)


@st.composite
def thresholds(draw: st.DrawFn) -> AppearanceThresholds:
    lo = draw(st.floats(0, 100))
    return AppearanceThresholds(t_lower=lo, t_upper=lo + draw(st.floats(0.01, 100)), t_recover=draw(st.floats(0.01, 100)))


@st.composite
def embeddings_msgs(draw: st.DrawFn) -> Embeddings:
    dim, n = draw(st.integers(1, 64)), draw(st.integers(0, 6))
    card = ModelCard(name=draw(names), dim=dim, metric=draw(st.sampled_from(["euclidean", "cosine"])),
                     input_size=draw(st.none() | st.tuples(st.integers(1, 512), st.integers(1, 512))),
                     normalized=draw(st.booleans()), thresholds=draw(st.none() | thresholds()))
    idx = np.array(draw(st.lists(st.integers(0, 10**6), min_size=n, max_size=n, unique=True)), dtype=np.int32)
    vecs = draw(hnp.arrays(np.float32, (n, dim), elements=st.floats(-10, 10, width=32)))
    return Embeddings(header=draw(headers), model=card, indices=idx, vectors=vecs)


tracks_msgs = st.builds(
    Tracks,
    header=headers,
    tracks=st.lists(
        st.builds(TrackState, id=st.integers(0, 10**6), status=st.sampled_from(["tentative", "confirmed", "deleted"]),
                  position=vec(3), velocity=vec(3), covariance=hnp.arrays(np.float64, (6, 6), elements=finite),
                  last_update_ns=stamps, hits=st.integers(0, 10**6), age_s=st.floats(0, 1e6),
                  misses=st.integers(0, 100), appearance_available=st.booleans()),
        max_size=4,
    ),
    appearance_available=st.booleans(),
    embedding_model=st.text(max_size=8),
    note=st.text(max_size=20),
    input_stamp_ns=stamps,
)
forget_msgs = st.builds(
    ForgetReply, header=headers, forgotten_ids=st.lists(st.integers(0, 10**6), max_size=4),
    descriptors_removed=st.integers(0, 10**6), classifiers_removed=st.integers(0, 100),
    live_tracks_cleared=st.lists(st.integers(0, 10**6), max_size=4), error=st.text(max_size=20),
)
head_command_msgs = st.builds(
    HeadCommand, header=headers, pan_rate=finite, tilt_rate=finite,
    mode=st.sampled_from(["track", "hold", "rest", "idle", "blind"]), target_id=st.integers(-1, 10**6),
    error_px=st.tuples(finite, finite), timeout_s=st.floats(1e-3, 10.0), input_stamp_ns=stamps,
)
attention_reply_msgs = st.builds(
    AttentionReply, header=headers, mode=st.sampled_from(["none", "nearest", "id"]), requested_id=st.integers(-1, 10**6),
    following_id=st.integers(-1, 10**6), known_ids=st.lists(st.integers(0, 10**6), max_size=4), error=st.text(max_size=20),
)
status_msgs = st.builds(
    ServiceStatus, header=headers, name=names, instance=st.text(max_size=10), host=st.text(max_size=10),
    pid=st.integers(0, 2**22), version=st.text(max_size=8), uptime_s=st.floats(0, 1e7),
    received=st.integers(0, 2**40), published=st.integers(0, 2**40), dropped=st.integers(0, 2**40),
    invalid=st.integers(0, 2**40), extra=st.dictionaries(st.text(max_size=8), finite, max_size=4),
)

groundtruth_msgs = st.builds(
    PeopleGroundTruth,
    header=headers,
    people=st.lists(
        st.builds(PersonGroundTruth, id=st.integers(0, 10**6), position=vec(3), velocity=vec(3),
                  visible_fraction=st.floats(0, 1), in_view_fraction=st.floats(0, 1), counted=st.booleans(),
                  posture=st.sampled_from(["standing", "sitting"]), height_m=st.floats(0, 3),
                  clothing=st.text(max_size=12), outfit=st.integers(0, 10)),
        max_size=4,
    ),
    min_visible=st.floats(0, 1),
)

#: One strategy per registered message type, by schema name.
MESSAGE_STRATEGIES = {
    "perception.Image": images(),
    "perception.CameraInfo": camera_infos(),
    "perception.RGBDFrame": rgbd_frames(),
    "perception.TransformBatch": transform_batches,
    "perception.Detections": detections_msgs,
    "perception.LocalizedDetections": localized_msgs,
    "perception.Embeddings": embeddings_msgs(),
    "perception.Tracks": tracks_msgs,
    "perception.ForgetReply": forget_msgs,
    "perception.HeadCommand": head_command_msgs,
    "perception.AttentionReply": attention_reply_msgs,
    "perception.ServiceStatus": status_msgs,
    "perception.PeopleGroundTruth": groundtruth_msgs,
}
