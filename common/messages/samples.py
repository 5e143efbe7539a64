"""Realistic example messages of every type, for self-checks, tests and benchmarks."""

from __future__ import annotations

import time

import numpy as np

from common.messages.schemas import (
    AppearanceThresholds,
    CameraInfo,
    CameraView,
    FloorCameraView,
    Detection,
    Detections,
    AttentionReply,
    Embeddings,
    ForgetReply,
    HandOverState,
    HeadCommand,
    Header,
    IdCandidateState,
    IdDecisions,
    IdDecisionState,
    Image,
    LocalizedDetection,
    LocalizedDetections,
    Message,
    ModelCard,
    PeopleGroundTruth,
    PersonGroundTruth,
    RGBDFrame,
    ServiceStatus,
    TrackState,
    Tracks,
    Transform,
    LaserScan,
    StaticMap,
    TransformBatch,
)

#: Intrinsics of a typical 640x480 RGB-D camera (Kinect/Astra class).
DEFAULT_K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])


def camera_info(width: int = 640, height: int = 480, stamp_ns: int = 0, frame_id: str = "camera") -> CameraInfo:
    """A distortion-free pinhole camera, with the focal length scaled to ``width``."""
    k = DEFAULT_K.copy()
    k[:2] *= width / 640.0
    k[0, 2], k[1, 2] = (width - 1) / 2.0, (height - 1) / 2.0
    return CameraInfo(
        header=Header(stamp_ns=stamp_ns, frame_id=frame_id, source="head"),
        width=width,
        height=height,
        K=k,
        D=np.zeros(5),
        distortion_model="plumb_bob",
    )


def rgbd_frame(width: int = 640, height: int = 480, seq: int = 0, stamp_ns: int | None = None, seed: int = 0) -> RGBDFrame:
    """A frame of noise-like RGB and a depth ramp in millimetres."""
    rng = np.random.default_rng(seed)
    stamp = time.time_ns() if stamp_ns is None else stamp_ns
    header = Header(stamp_ns=stamp, frame_id="camera", seq=seq, source="head")
    rgb = rng.integers(0, 256, size=(height, width, 3), dtype=np.uint8)
    depth = np.tile(np.linspace(500, 8000, width, dtype=np.uint16), (height, 1))
    return RGBDFrame(
        header=header,
        rgb=Image.from_array(rgb, "rgb8", header),
        depth=Image.from_array(depth, "16UC1", header),
        camera_info=camera_info(width, height, stamp, "camera"),
    )


def example_messages(stamp_ns: int = 1_700_000_000_000_000_000, n_people: int = 3) -> list[Message]:
    """One message of every registered type, filled with plausible values."""
    rng = np.random.default_rng(7)
    cam = Header(stamp_ns=stamp_ns, frame_id="camera", seq=42, source="head")
    map_header = Header(stamp_ns=stamp_ns, frame_id="map", seq=42, source="head")
    boxes = [(100.0 + 150 * i, 80.0, 160.0 + 150 * i, 300.0) for i in range(n_people)]
    small = rng.integers(0, 256, size=(48, 64, 3), dtype=np.uint8)
    card = ModelCard(
        name="colour",
        dim=128,
        metric="euclidean",
        input_size=(128, 64),
        normalized=True,
        thresholds=AppearanceThresholds(t_lower=0.3, t_upper=0.7, t_recover=0.4),
    )
    vectors = rng.normal(size=(n_people, 128)).astype(np.float32)
    return [
        Image.from_array(small, "rgb8", cam),
        Image.from_array(small, "jpeg", cam),
        camera_info(stamp_ns=stamp_ns),
        rgbd_frame(64, 48, seq=42, stamp_ns=stamp_ns),
        TransformBatch(
            header=Header(stamp_ns=stamp_ns, frame_id="map", seq=1, source="localization"),
            transforms=[
                Transform(
                    parent_frame="map",
                    child_frame="odom",
                    stamp_ns=stamp_ns,
                    translation=np.array([1.0, -0.5, 0.0]),
                    rotation_xyzw=np.array([0.0, 0.0, 0.0998334, 0.9950042]),
                ),
                Transform(
                    parent_frame="base_link",
                    child_frame="camera",
                    stamp_ns=stamp_ns,
                    translation=np.array([0.1, 0.0, 1.2]),
                    rotation_xyzw=np.array([-0.5, 0.5, -0.5, 0.5]),
                    static=True,
                ),
            ],
        ),
        Detections(
            header=cam,
            detections=[Detection(index=i, bbox_xyxy=b, score=0.9 - 0.1 * i) for i, b in enumerate(boxes)],
            image_width=640,
            image_height=480,
            detector="hog",
            inference_ms=12.5,
        ),
        LocalizedDetections(
            header=map_header,
            camera_frame="camera",
            detections=[
                LocalizedDetection(
                    index=i,
                    bbox_xyxy=b,
                    score=0.9,
                    position=np.array([2.0 + i, 0.5 * i, 0.9]),
                    cov=np.diag([0.01, 0.01, 0.04]),
                    depth_m=2.0 + i,
                    valid_pixels=900,
                )
                for i, b in enumerate(boxes)
            ],
            rejected={"too_few_valid_pixels": 1},
            view=CameraView(camera_to_frame=np.array([[0.0, 0, 1, 0.1], [-1, 0, 0, 0], [0, -1, 0, 1.2], [0, 0, 0, 1]]),
                            K=np.array([[525.0, 0, 320], [0, 525.0, 240], [0, 0, 1]]), width=640, height=480,
                            max_range_m=10.0),
            floor_view=FloorCameraView(image_to_frame=np.array([[0.01, 0, -3.2], [0, -0.01, 6.0], [0, 0, 1]]),
                                       width=640, height=480),
        ),
        Embeddings(header=cam, model=card, indices=np.arange(n_people, dtype=np.int32), vectors=vectors),
        Tracks(
            header=map_header,
            tracks=[
                TrackState(
                    id=i + 1,
                    status="confirmed",
                    position=np.array([2.0 + i, 0.5 * i, 0.9]),
                    velocity=np.array([0.3, 0.0, 0.0]),
                    covariance=np.eye(6) * 0.04,
                    last_update_ns=stamp_ns,
                    hits=12,
                    age_s=4.5,
                )
                for i in range(n_people)
            ],
            appearance_available=True,
            embedding_model="colour",
        ),
        IdDecisions(header=map_header, decisions=[
            IdDecisionState(id=3, outcome="recovered", x=2.2, y=2.5, support=0.85, threshold=0.5, p_new=0.07,
                            stranger_log_odds=0.4, candidates=[
                                IdCandidateState(id=3, log_odds=2.99, support=0.85, reachable=True, walked_out=False,
                                                 away_s=10.3, distance_m=2.7),
                                IdCandidateState(id=2, log_odds=0.59, support=0.08, reachable=True, walked_out=True,
                                                 away_s=5.6, distance_m=3.0)],
                            summary="ID 3 recovered at (2.20, 2.50) m: support 0.85 >= 0.50"),
            IdDecisionState(id=1, outcome="handover", x=-1.5, y=0.2, support=0.0, threshold=13.8, p_new=0.0,
                            handover=HandOverState(camera="back", d2=2.1, away_s=2.4, distance_m=0.6)),
            IdDecisionState(id=4, outcome="recovered", x=0.4, y=1.8, support=1.0, threshold=0.38, p_new=0.0,
                            rule="nearest", candidates=[
                                IdCandidateState(id=4, log_odds=3.1, support=1.0, reachable=True, distance=0.22)],
                            summary="ID 4 recovered at (0.40, 1.80) m (Algorithm 2): descriptor distance 0.22 < 0.38")]),
        ForgetReply(header=Header(stamp_ns=stamp_ns, frame_id="map", source="tracker"), forgotten_ids=[2],
                    descriptors_removed=140, classifiers_removed=1, live_tracks_cleared=[2]),
        HeadCommand(header=Header(stamp_ns=stamp_ns, frame_id="base_link", source="attention"), pan_rate=0.21,
                    tilt_rate=-0.05, mode="track", target_id=1, error_px=(-23.5, 6.0), input_stamp_ns=stamp_ns),
        AttentionReply(header=Header(stamp_ns=stamp_ns, frame_id="map", source="attention"), mode="id", requested_id=1,
                       following_id=1, known_ids=[1, 2]),
        ServiceStatus(
            header=Header(stamp_ns=stamp_ns, source="tracker"),
            name="tracker",
            instance="nav-pc-1234",
            host="nav-pc",
            pid=1234,
            version="0.1.0",
            uptime_s=12.5,
            received=300,
            published=299,
            dropped=1,
            invalid=0,
            extra={"tracks_confirmed": 3.0},
        ),
        PeopleGroundTruth(
            header=map_header,
            people=[
                PersonGroundTruth(
                    id=i + 1,
                    position=np.array([2.0 + i, 0.5 * i, 1.2]),
                    velocity=np.array([0.5, 0.0, 0.0]),
                    visible_fraction=1.0 - 0.4 * i,
                    counted=i < 2,
                    height_m=1.75,
                    clothing="red sweater, blue jeans",
                )
                for i in range(n_people)
            ],
        ),
        StaticMap(header=Header(stamp_ns=stamp_ns, frame_id="map", source="ros2"), resolution=0.05, width=4, height=3,
                  origin=(-1.0, -2.0, 0.0), data=bytes([0, 0, 100, 255] * 3)),
        LaserScan(header=Header(stamp_ns=stamp_ns, frame_id="base_laser", source="front"), angle_min=-0.5,
                  angle_max=0.5, angle_increment=0.25, time_increment=1e-4, scan_time=0.1, range_min=0.05,
                  range_max=10.0, ranges=np.array([1.0, 0.0, float("nan"), 2.5, 30.0], np.float32)),
    ]
