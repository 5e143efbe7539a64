"""Every message on the wire, as versioned pydantic v2 models.

Conventions (shared by every service):

* ``header.stamp_ns`` is the *sensor* time of the source frame in nanoseconds, and
  ``header.seq`` its sequence number. Derived messages (detections, localized detections,
  embeddings) copy both from the frame they were computed from, so they can be joined
  on ``(header.source, header.stamp_ns, header.seq)``.
* ``header.source`` names the sensor stream the data comes from (for example the camera
  name ``head``); ``header.frame_id`` is the coordinate frame of the payload.
* Transforms follow the ROS TF convention: a transform ``parent -> child`` maps points
  expressed in ``child`` into ``parent`` (``p_parent = R @ p_child + t``).
* Units are SI: metres, seconds (``*_s``), nanoseconds (``*_ns``), pixels for boxes.
* Within one schema version fields are only ever added, each with a default; decoders
  ignore fields they do not know, so a newer publisher can talk to an older subscriber.
"""

from __future__ import annotations

import math
from typing import Any, Callable, ClassVar, Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from common.messages.arrays import NDArray, arrays_equal

__all__ = [
    "MESSAGE_TYPES",
    "StaticMap",
    "AppearanceThresholds",
    "CameraInfo",
    "CameraView",
    "FloorCameraView",
    "Detection",
    "AttentionReply",
    "Detections",
    "Embeddings",
    "ForgetReply",
    "HandOverState",
    "HeadCommand",
    "Header",
    "IdCandidateState",
    "IdDecisionState",
    "IdDecisions",
    "Image",
    "LaserScan",
    "LocalizedDetection",
    "LocalizedDetections",
    "Message",
    "ModelCard",
    "PeopleGroundTruth",
    "PersonGroundTruth",
    "RGBDFrame",
    "ScanCoverage",
    "ServiceStatus",
    "TrackState",
    "Tracks",
    "Transform",
    "TransformBatch",
]

M = TypeVar("M", bound="Message")

#: Every top-level message type by its schema name.
MESSAGE_TYPES: dict[str, type[Message]] = {}


class _Model(BaseModel):
    model_config = ConfigDict(
        extra="ignore",
        arbitrary_types_allowed=True,
        ser_json_bytes="base64",
        val_json_bytes="base64",
        ser_json_inf_nan="constants",
    )

    def __eq__(self, other: object) -> bool:
        if type(self) is not type(other):
            return NotImplemented
        assert isinstance(other, BaseModel)
        return arrays_equal(self.model_dump(), other.model_dump())

    __hash__ = None  # type: ignore[assignment]


class Header(_Model):
    """Time, frame and origin of a message."""

    stamp_ns: int = Field(ge=0, description="sensor time of the source data, ns since the epoch")
    frame_id: str = Field(default="", description="coordinate frame of the payload")
    seq: int = Field(default=0, ge=0, description="sequence number of the source frame")
    source: str = Field(default="", description="sensor stream the data derives from, e.g. 'head'")

    @property
    def join_key(self) -> tuple[int, str, int]:
        """``(stamp_ns, source, seq)``: what every message derived from one source frame shares.

        Streams are joined on it (:class:`common.runtime.join.Joiner`), and it sorts in sensor time.
        """
        return (self.stamp_ns, self.source, self.seq)


class Message(_Model):
    """Base of every top-level message. ``SCHEMA_NAME`` and ``SCHEMA_VERSION`` travel with it."""

    SCHEMA_NAME: ClassVar[str] = ""
    SCHEMA_VERSION: ClassVar[int] = 0

    header: Header


def message(name: str, version: int) -> Callable[[type[M]], type[M]]:
    """Register a message class under a schema name and version."""

    def register(cls: type[M]) -> type[M]:
        if name in MESSAGE_TYPES:
            raise ValueError(f"schema {name!r} registered twice")
        cls.SCHEMA_NAME = name
        cls.SCHEMA_VERSION = version
        MESSAGE_TYPES[name] = cls
        return cls

    return register


def _finite(values: Any, what: str) -> None:
    # every message's arrays pass here on every decode: the method form skips numpy's
    # dispatch layers (about half the cost of np.all on small arrays)
    if not np.isfinite(np.asarray(values, dtype=np.float64)).all():
        raise ValueError(f"{what} must be finite")


# --------------------------------------------------------------------------- images

ImageEncoding = Literal["rgb8", "bgr8", "mono8", "16UC1", "32FC1", "jpeg", "png"]
_RAW_LAYOUT: dict[str, tuple[str, int]] = {
    "rgb8": ("uint8", 3),
    "bgr8": ("uint8", 3),
    "mono8": ("uint8", 1),
    "16UC1": ("uint16", 1),  # depth in millimetres, 0 = invalid
    "32FC1": ("float32", 1),  # depth in metres, NaN or 0 = invalid
}


@message("perception.Image", 1)
class Image(Message):
    """An image as raw bytes plus dtype and shape.

    Raw encodings hold ``data`` row-major with ``shape`` ``(H, W)`` or ``(H, W, 3)``.
    ``jpeg`` and ``png`` hold the compressed file, and ``shape``/``dtype`` describe the
    decoded image (a 16-bit PNG is a millimetre depth image).
    """

    encoding: ImageEncoding
    dtype: Literal["uint8", "uint16", "float32"]
    shape: tuple[int, ...]
    data: bytes

    @property
    def height(self) -> int:
        return self.shape[0]

    @property
    def width(self) -> int:
        return self.shape[1]

    @property
    def is_depth(self) -> bool:
        return self.encoding in ("16UC1", "32FC1") or (self.encoding == "png" and self.dtype == "uint16")

    @model_validator(mode="after")
    def _check_layout(self) -> Image:
        if len(self.shape) not in (2, 3) or any(d <= 0 for d in self.shape):
            raise ValueError(f"shape must be (H, W) or (H, W, C) with positive sizes, got {self.shape}")
        if len(self.shape) == 3 and self.shape[2] not in (1, 3, 4):
            raise ValueError(f"channel count must be 1, 3 or 4, got {self.shape[2]}")
        layout = _RAW_LAYOUT.get(self.encoding)
        if layout is None:  # compressed
            if not self.data:
                raise ValueError(f"{self.encoding} image has no data")
            if self.encoding == "jpeg" and self.dtype != "uint8":
                raise ValueError("jpeg images are uint8")
            return self
        dtype, channels = layout
        if self.dtype != dtype:
            raise ValueError(f"encoding {self.encoding} needs dtype {dtype}, got {self.dtype}")
        got_channels = self.shape[2] if len(self.shape) == 3 else 1
        if got_channels != channels:
            raise ValueError(f"encoding {self.encoding} needs {channels} channel(s), got {got_channels}")
        expected = math.prod(self.shape) * np.dtype(dtype).itemsize
        if len(self.data) != expected:
            raise ValueError(f"data holds {len(self.data)} bytes, shape {self.shape} of {dtype} needs {expected}")
        return self

    @classmethod
    def from_array(cls, array: np.ndarray, encoding: ImageEncoding, header: Header, quality: int = 90) -> Image:
        """Build an image message from an array.

        ``array`` is (H, W, 3) uint8 for rgb8/bgr8 (in that channel order), (H, W) uint8
        for mono8, (H, W) uint16 millimetres for 16UC1, (H, W) float32 metres for 32FC1.
        ``jpeg``/``png`` compress an RGB (H, W, 3) uint8 array, or for png also a
        (H, W) uint16 depth image.
        """
        arr = np.ascontiguousarray(array)
        if encoding in _RAW_LAYOUT:
            return cls(header=header, encoding=encoding, dtype=arr.dtype.name, shape=arr.shape, data=arr.tobytes())
        import cv2

        to_write = cv2.cvtColor(arr, cv2.COLOR_RGB2BGR) if arr.ndim == 3 else arr
        params = [cv2.IMWRITE_JPEG_QUALITY, quality] if encoding == "jpeg" else []
        ok, buf = cv2.imencode("." + ("jpg" if encoding == "jpeg" else "png"), to_write, params)
        if not ok:
            raise ValueError(f"could not encode a {arr.dtype.name} {arr.shape} array as {encoding}")
        return cls(header=header, encoding=encoding, dtype=arr.dtype.name, shape=arr.shape, data=buf.tobytes())

    def to_array(self) -> np.ndarray:
        """The pixels: RGB order for colour images (bgr8 and compressed are converted)."""
        if self.encoding in _RAW_LAYOUT:
            arr = np.frombuffer(self.data, dtype=self.dtype).reshape(self.shape)
            return arr[..., ::-1] if self.encoding == "bgr8" else arr
        import cv2

        decoded = cv2.imdecode(np.frombuffer(self.data, np.uint8), cv2.IMREAD_UNCHANGED)
        if decoded is None:
            raise ValueError(f"{self.encoding} data could not be decoded")
        if decoded.ndim == 3:
            decoded = cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB)
        if decoded.shape != self.shape:
            raise ValueError(f"decoded {self.encoding} has shape {decoded.shape}, header says {self.shape}")
        return decoded

    def depth_m(self) -> np.ndarray:
        """Depth in metres as (H, W) float32, invalid pixels (0, NaN) as NaN."""
        if not self.is_depth:
            raise ValueError(f"encoding {self.encoding} is not a depth image (use 16UC1 or 32FC1)")
        arr = self.to_array()
        if arr.dtype == np.uint16:
            out = arr.astype(np.float32) * np.float32(0.001)
        else:
            out = arr.astype(np.float32, copy=True)
        out[~(out > 0)] = np.nan
        return out


@message("perception.CameraInfo", 1)
class CameraInfo(Message):
    """Pinhole intrinsics and distortion of a camera (ROS ``sensor_msgs/CameraInfo``)."""

    width: int = Field(gt=0)
    height: int = Field(gt=0)
    K: NDArray(np.float64, (3, 3))  # type: ignore[valid-type]
    D: NDArray(np.float64, (None,)) = Field(default_factory=lambda: np.zeros(0))  # type: ignore[valid-type]
    distortion_model: Literal["plumb_bob", "rational_polynomial", "equidistant", "none"] = "plumb_bob"

    @model_validator(mode="after")
    def _check(self) -> CameraInfo:
        _finite(self.K, "K")
        _finite(self.D, "D")
        if not (self.K[0, 0] > 0 and self.K[1, 1] > 0):
            raise ValueError("K: focal lengths fx = K[0,0] and fy = K[1,1] must be positive")
        k20, k21, k22 = self.K[2].tolist()
        if abs(k20) > 1e-9 or abs(k21) > 1e-9 or abs(k22 - 1.0) > 1e-9:
            raise ValueError("K: last row must be [0, 0, 1]")
        allowed = {"plumb_bob": (0, 5), "rational_polynomial": (0, 8), "equidistant": (0, 4), "none": (0,)}
        if len(self.D) not in allowed[self.distortion_model]:
            raise ValueError(f"D: {self.distortion_model} takes {allowed[self.distortion_model]} coefficients, got {len(self.D)}")
        return self



@message("perception.RGBDFrame", 1)
class RGBDFrame(Message):
    """The colour image, the registered depth image and the intrinsics of one instant.

    Depth is registered to the colour image (same size, same intrinsics). It may be
    absent on an RGB-only camera.
    """

    rgb: Image
    depth: Image | None = None
    camera_info: CameraInfo

    @model_validator(mode="after")
    def _check(self) -> RGBDFrame:
        if self.rgb.is_depth:
            raise ValueError(f"rgb: encoding {self.rgb.encoding} is a depth encoding")
        if self.depth is not None:
            if not self.depth.is_depth:
                raise ValueError(f"depth: encoding {self.depth.encoding} is not 16UC1, 32FC1 or 16-bit png")
            if self.depth.shape[:2] != self.rgb.shape[:2]:
                raise ValueError(f"depth: shape {self.depth.shape[:2]} differs from rgb {self.rgb.shape[:2]}")
        if (self.camera_info.height, self.camera_info.width) != self.rgb.shape[:2]:
            raise ValueError("camera_info: width/height differ from the rgb image")
        return self


# ----------------------------------------------------------------------- transforms


class Transform(_Model):
    """Pose of ``child_frame`` in ``parent_frame`` at ``stamp_ns`` (ROS TF convention)."""

    parent_frame: str = Field(min_length=1)
    child_frame: str = Field(min_length=1)
    stamp_ns: int = Field(ge=0)
    translation: NDArray(np.float64, (3,))  # type: ignore[valid-type]
    rotation_xyzw: NDArray(np.float64, (4,))  # type: ignore[valid-type]
    static: bool = False

    @field_validator("translation")
    @classmethod
    def _finite_translation(cls, v: np.ndarray) -> np.ndarray:
        _finite(v, "translation")
        return v

    @field_validator("rotation_xyzw")
    @classmethod
    def _unit_quaternion(cls, v: np.ndarray) -> np.ndarray:
        _finite(v, "rotation_xyzw")
        norm = float(np.linalg.norm(v))
        if not 0.5 < norm < 1.5:
            raise ValueError(f"rotation_xyzw must be a unit quaternion, norm is {norm:.3g}")
        # Normalise only when off by more than rounding, so decoding is idempotent.
        return v if abs(norm - 1.0) < 1e-12 else v / norm

    @model_validator(mode="after")
    def _distinct(self) -> Transform:
        if self.parent_frame == self.child_frame:
            raise ValueError(f"parent_frame and child_frame are both {self.parent_frame!r}")
        return self


@message("perception.TransformBatch", 1)
class TransformBatch(Message):
    """Transforms published together, e.g. one TF message or the static transforms."""

    transforms: list[Transform]


@message("perception.StaticMap", 1)
class StaticMap(Message):
    """The robot's static map, a ROS ``nav_msgs/OccupancyGrid`` (the ros2 node reads ``/map``):
    ``width`` x ``height`` cells of ``resolution`` m in ``header.frame_id``, cell (0, 0)'s outer
    corner at ``origin`` (x, y, yaw), row 0 at the lowest y; ``data`` one signed byte per cell, row
    by row: the occupancy in percent (0 to 100), -1 unknown."""

    resolution: float = Field(gt=0.0, allow_inf_nan=False)
    width: int = Field(gt=0)
    height: int = Field(gt=0)
    origin: tuple[float, float, float]
    data: bytes

    @model_validator(mode="after")
    def _check(self) -> StaticMap:
        _finite(self.origin, "origin")
        if len(self.data) != self.width * self.height:
            raise ValueError(f"data holds {len(self.data)} cells, width x height is {self.width * self.height}")
        return self

    def occupancy(self) -> np.ndarray:
        """(height, width) int8: percent, -1 unknown."""
        return np.frombuffer(self.data, np.int8).reshape(self.height, self.width)

    def content(self) -> tuple[object, ...]:
        """What makes it this map, its stamp aside: a map sent again has the same content."""
        return (self.header.frame_id, self.resolution, self.width, self.height, self.origin, hash(self.data))


# ---------------------------------------------------------------------------- laser

#: ROS drivers disagree by one beam on whether angle_max is the last beam's angle or one past it.
_BEAM_SLACK = 1


@message("perception.LaserScan", 1)
class LaserScan(Message):
    """One sweep of a 2-D laser scanner, as ROS's ``sensor_msgs/LaserScan``: beam ``i`` points at
    ``angle_min + i * angle_increment`` rad (counter-clockwise about z of ``header.frame_id``, the
    scanner's frame), ``ranges[i]`` m; ``header.stamp_ns`` is the first beam's time and beam ``i``
    was measured ``i * time_increment`` s later. A range that is NaN, inf or outside
    (``range_min``, ``range_max``) is no return: kept as sent, counted by the reader, never an
    error. ``header.source`` names the scanner stream (``front``, ``rear``)."""

    angle_min: float = Field(allow_inf_nan=False)
    angle_max: float = Field(allow_inf_nan=False)
    angle_increment: float = Field(gt=0.0, allow_inf_nan=False, description="rad between beams; > 0")
    time_increment: float = Field(default=0.0, allow_inf_nan=False, description="s between beams")
    scan_time: float = Field(default=0.0, ge=0.0, allow_inf_nan=False, description="s between scans")
    range_min: float = Field(ge=0.0, allow_inf_nan=False)
    range_max: float = Field(gt=0.0, allow_inf_nan=False)
    ranges: NDArray(np.float32, (None,))  # type: ignore[valid-type]
    intensities: NDArray(np.float32, (None,)) | None = Field(  # type: ignore[valid-type]
        default=None, description="one per range when the scanner sends them")

    @model_validator(mode="after")
    def _check(self) -> LaserScan:
        if self.range_min >= self.range_max:
            raise ValueError(f"range_min {self.range_min} must be below range_max {self.range_max}")
        n = len(self.ranges)
        if n == 0:
            raise ValueError("ranges is empty")
        span = (self.angle_max - self.angle_min) / self.angle_increment
        if span < -0.5 or abs(span + 1 - n) > _BEAM_SLACK + 1e-3 * n:
            raise ValueError(f"{n} ranges do not fit angle_min {self.angle_min:.4f} .. angle_max "
                             f"{self.angle_max:.4f} in steps of {self.angle_increment:.6f} rad "
                             f"({span + 1:.1f} beams)")
        if self.intensities is not None and len(self.intensities) not in (0, n):
            raise ValueError(f"{len(self.intensities)} intensities for {n} ranges")
        return self

    @classmethod
    def from_ros(cls, msg: Any, source: str, seq: int = 0) -> LaserScan:
        """A ``sensor_msgs/LaserScan`` (ROS 1 or 2, as ``rosbags`` or rclpy give it; duck-typed)
        -> :class:`LaserScan`. Raises ``ValueError`` (pydantic's) naming a bad field."""
        stamp = msg.header.stamp
        nanos = getattr(stamp, "nanosec", None)
        stamp_ns = int(stamp.sec) * 1_000_000_000 + int(getattr(stamp, "nsec", 0) if nanos is None else nanos)
        intensities = np.asarray(msg.intensities, np.float32)
        return cls(header=Header(stamp_ns=max(0, stamp_ns), frame_id=str(msg.header.frame_id).lstrip("/"),
                                 seq=seq, source=source),
                   angle_min=float(msg.angle_min), angle_max=float(msg.angle_max),
                   angle_increment=float(msg.angle_increment), time_increment=float(msg.time_increment),
                   scan_time=max(0.0, float(msg.scan_time)), range_min=float(msg.range_min),
                   range_max=float(msg.range_max), ranges=np.asarray(msg.ranges, np.float32),
                   intensities=intensities if len(intensities) else None)


# ------------------------------------------------------------------------ detections

BBox = tuple[float, float, float, float]


#: A person's posture as a detector saw it (None: the detector cannot tell).
Posture = Literal["standing", "sitting", "lying"]


class Detection(_Model):
    """One person box in pixel coordinates of the source image."""

    index: int = Field(ge=0, description="position of this detection in its frame")
    bbox_xyxy: BBox
    score: float = Field(ge=0.0, le=1.0)
    class_id: int = 0
    class_name: str = "person"
    posture: Posture | None = Field(default=None, description="the posture the detector saw (the depth detector: "
                                    "standing or sitting); None: it cannot tell")
    depth_m: float | None = Field(default=None, gt=0.0, allow_inf_nan=False,
                                  description="the person's own depth (m) when the detector measured it from their "
                                  "points (the depth detector): the localizer takes it instead of the box's depth, "
                                  "which a nearer person overlapping the box can pull to theirs; None: not measured")
    stature_m: float | None = Field(default=None, gt=0.0, le=3.0, allow_inf_nan=False,
                                    description="a standing person's stature (m): the top of their points above the "
                                    "floor (the depth detector, when the image shows their head); the tracker "
                                    "weighs it as a soft biometric; None: not measured")

    @field_validator("bbox_xyxy")
    @classmethod
    def _finite_box(cls, v: BBox) -> BBox:
        _finite(v, "bbox_xyxy")
        return v


@message("perception.Detections", 1)
class Detections(Message):
    """All detections of one source frame; ``header`` is that frame's header."""

    detections: list[Detection] = Field(default_factory=list)
    image_width: int = Field(default=0, ge=0)
    image_height: int = Field(default=0, ge=0)
    detector: str = ""
    inference_ms: float | None = None


class LocalizedDetection(_Model):
    """A detection placed in the target frame (normally ``map``)."""

    index: int = Field(ge=0, description="index of the detection in its source frame")
    bbox_xyxy: BBox
    score: float = Field(ge=0.0, le=1.0)
    position: NDArray(np.float64, (3,))  # type: ignore[valid-type]
    cov: NDArray(np.float64, (3, 3))  # type: ignore[valid-type]
    depth_m: float = Field(gt=0.0, description="depth used along the optical axis")
    valid_pixels: int = Field(default=0, ge=0)
    posture: Posture | None = Field(default=None, description="the detector's posture, passed on")
    stature_m: float | None = Field(default=None, gt=0.0, le=3.0, allow_inf_nan=False,
                                    description="the detector's stature of a standing person (m), passed on")

    @model_validator(mode="after")
    def _check(self) -> LocalizedDetection:
        _finite(self.position, "position")
        _finite(self.cov, "cov")
        return self


class CameraView(_Model):
    """What the camera could see at a frame, in the frame of the positions: the tracker
    tells a person out of view from one the detector missed (it does not report the
    prediction of a person the camera could not see)."""

    camera_to_frame: NDArray(np.float64, (4, 4))  # type: ignore[valid-type]  # camera (z forward) -> header.frame_id
    K: NDArray(np.float64, (3, 3))  # type: ignore[valid-type]
    width: int = Field(gt=0)
    height: int = Field(gt=0)
    max_range_m: float = Field(gt=0.0, description="farthest depth the localizer uses")

    @model_validator(mode="after")
    def _check(self) -> CameraView:
        _finite(self.camera_to_frame, "camera_to_frame")
        _finite(self.K, "K")
        return self


class FloorCameraView(_Model):
    """What a fixed camera placed on the floor by a homography sees (no intrinsics needed):
    ``image_to_frame`` (3, 3) maps a foot pixel ``(u, v, 1)`` to ``(x, y, w)`` in the frame of
    the positions (metres after dividing by ``w``); a person is in view when their feet project
    inside the ``width`` x ``height`` image."""

    image_to_frame: NDArray(np.float64, (3, 3))  # type: ignore[valid-type]
    width: int = Field(gt=0)
    height: int = Field(gt=0)

    @model_validator(mode="after")
    def _check(self) -> FloorCameraView:
        _finite(self.image_to_frame, "image_to_frame")
        return self


class ScanCoverage(_Model):
    """What a 2-D laser could see in one sweep, in the frame of the positions: ``scanner_to_frame``
    (4, 4) the scanner's pose at the scan's stamp, beam ``i`` at ``angle_min + i * angle_increment``
    about the scanner's z returned at ``ranges[i]`` m (no return: ``max_range_m``, free as far as the
    detector looks). The tracker tells a person hidden behind a nearer return, or beyond the
    detector's range, from one the laser missed."""

    scanner_to_frame: NDArray(np.float64, (4, 4))  # type: ignore[valid-type]
    angle_min: float = Field(allow_inf_nan=False)
    angle_increment: float = Field(gt=0.0, allow_inf_nan=False)
    ranges: NDArray(np.float32, (None,))  # type: ignore[valid-type]
    max_range_m: float = Field(gt=0.0, allow_inf_nan=False, description="farthest range the detector looks at")

    @model_validator(mode="after")
    def _check(self) -> ScanCoverage:
        _finite(self.scanner_to_frame, "scanner_to_frame")
        _finite(self.ranges, "ranges")
        if not len(self.ranges):
            raise ValueError("ranges is empty")
        return self


@message("perception.LocalizedDetections", 1)
class LocalizedDetections(Message):
    """People positions of one source frame.

    ``header.stamp_ns``/``header.seq`` are the source frame's; ``header.source`` is the
    stream's name: the camera's, or the name a second detector on that camera publishes
    under (two detectors' results of one frame must not share a join key);
    ``header.frame_id`` is the frame the positions are in (``map``).
    """

    camera_frame: str = ""
    detections: list[LocalizedDetection] = Field(default_factory=list)
    rejected: dict[str, int] = Field(default_factory=dict, description="boxes rejected in this frame, by reason")
    view: CameraView | None = Field(default=None, description="the camera's view at this frame (None: not known)")
    floor_view: FloorCameraView | None = Field(
        default=None, description="a fixed camera's view through its floor homography (None: not placed by one)")
    scan_view: ScanCoverage | None = Field(
        default=None, description="a 2-D laser's view at this scan (None: not a laser's frame)")
    detector: str = Field(default="", description="the detector whose boxes these are (Detections.detector)")


# ------------------------------------------------------------------------ embeddings


class AppearanceThresholds(_Model):
    """Tracker thresholds on this model's distance scale (Pinto's thesis, Algorithms 1 and 2)."""

    t_lower: float = Field(ge=0.0)
    t_upper: float = Field(gt=0.0)
    t_recover: float = Field(gt=0.0)

    @model_validator(mode="after")
    def _ordered(self) -> AppearanceThresholds:
        if not self.t_lower < self.t_upper:
            raise ValueError(f"t_lower ({self.t_lower}) must be below t_upper ({self.t_upper})")
        return self


class ModelCard(_Model):
    """What produced a set of descriptors. Descriptors of different models never mix."""

    name: str = Field(min_length=1)
    dim: int = Field(gt=0)
    metric: Literal["euclidean", "cosine"] = "euclidean"
    input_size: tuple[int, int] | None = Field(default=None, description="(H, W) of the model input")
    normalized: bool = False
    thresholds: AppearanceThresholds | None = None


@message("perception.Embeddings", 1)
class Embeddings(Message):
    """Appearance descriptors of one source frame, one per detection index."""

    model: ModelCard
    indices: NDArray(np.int32, (None,))  # type: ignore[valid-type]
    vectors: NDArray(np.float32, (None, None))  # type: ignore[valid-type]
    #: optional (N, 8) probabilities of the upper body's orientation relative to the camera
    #: (bin k: facing k * 45 degrees anticlockwise from towards the camera), per index
    orientation: NDArray(np.float32, (None, 8)) | None = None  # type: ignore[valid-type]

    @model_validator(mode="after")
    def _check(self) -> Embeddings:
        n = len(self.indices)
        if self.orientation is not None and self.orientation.shape[0] != n:
            raise ValueError(f"orientation: {self.orientation.shape[0]} rows for {n} indices")
        if self.vectors.shape[0] != n:
            raise ValueError(f"vectors: {self.vectors.shape[0]} rows for {n} indices")
        if n and self.vectors.shape[1] != self.model.dim:
            raise ValueError(f"vectors: dimension {self.vectors.shape[1]}, model {self.model.name} says {self.model.dim}")
        if len(set(self.indices.tolist())) != n:
            raise ValueError("indices: duplicate detection index")
        return self


# ---------------------------------------------------------------------------- tracks


class TrackState(_Model):
    """One track. ``covariance`` is over the state (x, y, z, vx, vy, vz)."""

    id: int = Field(ge=0)
    status: Literal["tentative", "confirmed", "coasting", "deleted"]
    position: NDArray(np.float64, (3,))  # type: ignore[valid-type]
    velocity: NDArray(np.float64, (3,))  # type: ignore[valid-type]
    covariance: NDArray(np.float64, (6, 6))  # type: ignore[valid-type]
    last_update_ns: int = Field(ge=0)
    hits: int = Field(ge=0)
    age_s: float = Field(ge=0.0)
    misses: int = Field(default=0, ge=0)
    appearance_available: bool = True
    posture: list[float] = Field(default_factory=lambda: [1 / 3] * 3, min_length=3, max_length=3,
                                 description="P(standing, sitting, lying); uniform: unknown")
    orientation: list[float] = Field(default_factory=lambda: [1 / 8] * 8, min_length=8, max_length=8,
                                     description="P(upper body faces bin k), bin k centred on k * 45 degrees in the "
                                                 "tracking frame (0 along +x); uniform: unknown")
    stature_m: float | None = Field(default=None, gt=0.0, le=3.0, allow_inf_nan=False,
                                    description="the person's stature (m), from the depth detector's measurements of "
                                    "them standing; None: not measured")


@message("perception.Tracks", 1)
class Tracks(Message):
    """The tracker's output after one update; ``header.frame_id`` is the tracking frame."""

    tracks: list[TrackState] = Field(default_factory=list)
    appearance_available: bool = True
    embedding_model: str = ""
    note: str = Field(default="", description="a query's answer when it has no track: why (e.g. not found)")
    input_stamp_ns: int = Field(default=0, ge=0, description="stamp of the newest input frame applied; at a fixed "
                                "output rate header.stamp_ns is the publish time the tracks are predicted to")


class IdCandidateState(_Model):
    """A remembered person an ID decision weighed (the tracker core's ``IdCandidate``)."""

    id: int = Field(ge=0)
    log_odds: float = Field(description="that the track is them: appearance, their classifier, the walked-out prior")
    support: float = Field(ge=0.0, le=1.0, description="their probability against someone new and their rivals")
    reachable: bool = Field(description="whether they could have walked here since they left")
    walked_out: bool | None = Field(default=None, description="left by walking out of the view (None: not known)")
    away_s: float | None = Field(default=None, ge=0.0, description="since they left")
    distance_m: float | None = Field(default=None, ge=0.0, description="from where they left")
    distance: float | None = Field(default=None, ge=0.0,
                                   description="descriptor distance to their nearest remembered view ('nearest' rule)")


class HandOverState(_Model):
    """A hand-over between cameras: the ID's track, last seen by ``camera``, predicted here."""

    camera: str
    d2: float = Field(ge=0.0, description="squared Mahalanobis distance of its prediction")
    away_s: float = Field(ge=0.0)
    distance_m: float = Field(ge=0.0)


class IdDecisionState(_Model):
    """Why a newly confirmed track got its ID, or lost a recovered one (the tracker core's ``IdDecision``)."""

    id: int = Field(ge=0, description="the ID the track has now")
    outcome: Literal["new", "recovered", "undone", "handover"]
    x: float
    y: float
    support: float = Field(ge=0.0, le=1.0, description="the best candidate's (for 'undone': the one taken back); "
                                                       "'nearest' rule: 1 when an ID was given back, else 0")
    threshold: float = Field(ge=0.0, description="p_recover, p_undo during probation, the hand-over's gate, or "
                                                 "t_recover (a descriptor distance) for the 'nearest' rule")
    p_new: float = Field(ge=0.0, le=1.0, description="the posterior of someone new")
    stranger_log_odds: float = 0.0
    candidates: list[IdCandidateState] = Field(default_factory=list, description="the most probable first")
    previous_id: int | None = Field(default=None, description="'undone': the remembered ID taken back")
    handover: HandOverState | None = None
    rule: Literal["open-set", "nearest"] = Field(
        default="open-set", description="the robust profile's open-set posterior, or Pinto's Algorithm 2 (thesis profile)")
    summary: str = Field(default="", description="the decision in one line, as the tracker logs it")


@message("perception.IdDecisions", 1)
class IdDecisions(Message):
    """Why the tracker gave IDs in one frame (``keys.id_decisions()``): ``header`` is the frame's,
    in the tracking frame. Sent only for frames with decisions (a few a minute where people come
    and go); a decision made again, the same, when late inputs re-apply frames is not sent again."""

    decisions: list[IdDecisionState] = Field(default_factory=list)


@message("perception.ForgetReply", 1)
class ForgetReply(Message):
    """The tracker's answer to a forget request (``keys.forget_query()``)."""

    forgotten_ids: list[int] = Field(default_factory=list, description="IDs whose appearance was removed")
    descriptors_removed: int = Field(default=0, ge=0, description="remembered and live descriptors removed")
    classifiers_removed: int = Field(default=0, ge=0)
    live_tracks_cleared: list[int] = Field(default_factory=list,
                                           description="live tracks that keep their ID but lost their appearance")
    error: str = Field(default="", description="why nothing was done (a malformed request, an unknown ID)")


# ------------------------------------------------------------------------- attention


@message("perception.HeadCommand", 1)
class HeadCommand(Message):
    """Pan/tilt velocities for the robot's head, from the attention node (``keys.head_command()``).

    ``header.stamp_ns`` is the sensor time the command was computed for (the tracks'
    stamp); ``header.frame_id`` the frame whose z axis is the pan axis (``base_link``).
    """

    pan_rate: float = Field(default=0.0, description="rad/s about the base's z axis; positive turns the head left")
    tilt_rate: float = Field(default=0.0, description="rad/s about the head's y axis; positive looks down")
    mode: Literal["track", "hold", "rest", "idle", "blind"] = Field(
        default="idle", description="track: servoing on target_id; hold: target lost, waiting; rest: returning to the "
                                    "rest pose; idle: at rest; blind: no camera info or transform, standing still")
    target_id: int = Field(default=-1, ge=-1, description="the person followed (track, hold), -1 for none")
    error_px: tuple[float, float] = Field(default=(0.0, 0.0),
                                          description="the target's image position minus the image centre (track)")
    timeout_s: float = Field(default=0.5, gt=0.0, description="the head stops if no newer command comes within this")
    input_stamp_ns: int = Field(default=0, ge=0, description="stamp of the Tracks message this command answers")

    @model_validator(mode="after")
    def _check(self) -> HeadCommand:
        _finite([self.pan_rate, self.tilt_rate, *self.error_px, self.timeout_s], "pan_rate, tilt_rate and error_px")
        return self


@message("perception.AttentionReply", 1)
class AttentionReply(Message):
    """The attention node's answer to a query on ``keys.attention_query()``: its state after the request."""

    mode: Literal["none", "nearest", "id", "lock"] = Field(
        default="none", description="what the node is told to look at ('lock' until someone is locked onto, then 'id')")
    requested_id: int = Field(default=-1, ge=-1, description="the ID asked for in mode 'id'")
    following_id: int = Field(default=-1, ge=-1, description="the person the head follows now, -1 for none")
    known_ids: list[int] = Field(default_factory=list, description="the IDs in the latest tracks")
    error: str = Field(default="", description="why the request was refused (an unknown ID, a malformed target)")


# ---------------------------------------------------------------------------- status


@message("perception.ServiceStatus", 1)
class ServiceStatus(Message):
    """Health and counters of one running service instance, or, with ``state`` ``failed``, of
    one that stopped for good (a configuration error), as its launcher reports it."""

    name: str = Field(min_length=1)
    instance: str = ""
    host: str = ""
    pid: int = 0
    version: str = ""
    uptime_s: float = Field(default=0.0, ge=0.0)
    received: int = Field(default=0, ge=0)
    published: int = Field(default=0, ge=0)
    dropped: int = Field(default=0, ge=0)
    invalid: int = Field(default=0, ge=0)
    extra: dict[str, float] = Field(default_factory=dict, description="service-specific counters and gauges")
    state: Literal["running", "failed"] = Field(
        default="running", description="'failed': the service stopped and is not restarted (reported by its launcher)")
    error: str = Field(default="", description="why a failed service stopped: its last error line")
    exit_status: int | None = Field(default=None, description="a failed service's exit status")
    subscribes: list[str] = Field(default_factory=list, description="the keys the service subscribes to")
    publishes: list[str] = Field(default_factory=list, description="the keys the service publishes on")
    settings: dict[str, str] = Field(
        default_factory=dict, description="the service's top-level settings, as text (perception doctor reads them)")


# ---------------------------------------------------------------------- ground truth


class PersonGroundTruth(_Model):
    """Where one person really is, from a simulator or a motion-capture system (map frame)."""

    id: int = Field(ge=0, description="the person's identity; it stays the same when clothes change")
    position: NDArray(np.float64, (3,))  # type: ignore[valid-type]
    velocity: NDArray(np.float64, (3,)) = Field(default_factory=lambda: np.zeros(3))  # type: ignore[valid-type]
    visible_fraction: float = Field(default=1.0, ge=0.0, le=1.0, description="share of the body the camera sees")
    in_view_fraction: float = Field(default=1.0, ge=0.0, le=1.0, description="share of the body inside the image")
    counted: bool = Field(default=True, description="a ground-truth object of this frame (visible enough to be tracked)")
    posture: Literal["standing", "sitting"] = "standing"
    height_m: float = Field(default=0.0, ge=0.0)
    clothing: str = Field(default="", description="what the person wears, in words")
    outfit: int = Field(default=0, ge=0, description="index of the outfit worn; changes when the person changes clothes")
    facing_rad: float | None = Field(default=None, description="the direction the body faces in the map frame "
                                     "(rad, 0 along +x); None: not known")
    laser_seen: bool | None = Field(default=None, description="the robot's 2-D laser could see them (its beams "
                                    "hit their legs); None: no laser")

    @model_validator(mode="after")
    def _check(self) -> PersonGroundTruth:
        _finite(self.position, "position")
        _finite(self.velocity, "velocity")
        return self


@message("perception.PeopleGroundTruth", 1)
class PeopleGroundTruth(Message):
    """Every person's true position at one camera frame.

    ``header`` has the frame's stamp, seq and source (camera); ``header.frame_id`` is the
    frame of the positions (``map``). ``position`` is the torso centre. ``counted`` marks the
    people that are ground-truth objects for that camera (``visible_fraction >= min_visible``);
    the others are out of view or hidden and listed for debugging.
    """

    people: list[PersonGroundTruth] = Field(default_factory=list)
    min_visible: float = Field(default=0.25, ge=0.0, le=1.0)

    def counted(self) -> list[PersonGroundTruth]:
        """The people that count as ground-truth objects in this frame."""
        return [p for p in self.people if p.counted]

    def around(self) -> list[PersonGroundTruth]:
        """The people the robot's sensors could see: the camera's counted, and those its laser
        could see (``laser_seen``), all round the robot."""
        return [p for p in self.people if p.counted or p.laser_seen]
