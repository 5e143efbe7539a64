"""Settings of the depth-cluster detector (:mod:`services.detector.core.depth`), apart from
its code so that reading them (the config's defaults) does not import scipy."""

from __future__ import annotations

from dataclasses import dataclass, field

from services.detector.core.boxes import DetectorError
from services.detector.core.ground import GroundParams
from services.detector.core.seated import SeatedParams

__all__ = ["DepthParams"]


@dataclass(frozen=True)
class DepthParams:
    """Settings of :class:`DepthClusterDetector` (Basso/Munaro defaults)."""

    camera_height_m: float = 1.2
    tilt_deg: float = 0.0
    voxel_m: float = 0.06
    pixel_step: int = 2
    min_depth_m: float = 0.3
    max_depth_m: float = 8.0
    ground: GroundParams = field(default_factory=GroundParams)
    floor_clearance_m: float = 0.12
    max_point_height_m: float = 2.6
    cluster_tolerance_m: float = 0.13
    min_cluster_points: int = 15
    min_height_m: float = 1.4
    max_height_m: float = 2.3
    max_width_m: float = 1.5
    max_bottom_m: float = 0.6
    #: A whole cluster whose lowest points are hidden by something nearer (the back of a sofa,
    #: a table, a person in front) need not reach ``max_bottom_m``, only come down to this
    #: height (m): a person standing behind furniture is seen from the waist up. 0: off (the
    #: default: the localizer then takes the furniture's depth for theirs; the README).
    occluded_max_bottom_m: float = 0.0
    #: A point is hidden from below when the depth just under it in the image is nearer by this (m).
    occluder_gap_m: float = 0.25
    #: A person is not flat: the standard deviation of a cluster's floor footprint across its
    #: main direction must reach this (m). A wall's end or a door frame seen edge-on makes a
    #: person-tall, person-wide cluster of points on one vertical plane; a body's visible
    #: front curves by 10-20 cm. 0: off.
    min_thickness_m: float = 0.015
    #: A cluster wider than ``max_width_m`` (a person merged with a chair, a table or
    #: another person) is split by its parts above this height, one person per part.
    split_height_m: float = 1.05
    #: Radius on the ground plane around a split part's centre that belongs to that person.
    person_radius_m: float = 0.4
    #: Heads (Basso/Munaro's height-map maxima): a cluster's highest points above ``min_height_m``
    #: at least this far apart on the floor (m) are separate heads. A cluster with two or more
    #: is split, each point going to the nearest head within ``person_radius_m``: two people
    #: side by side, merged into one cluster below their heads. A person's shoulders lie
    #: within about 0.25 m of their head's centre. 0: off.
    head_separation_m: float = 0.4
    #: ... and between two heads the cluster must dip this much (m) below the lower one.
    head_dip_m: float = 0.15
    #: A standing person's top is a head: where nothing hides it from above, the cluster's points
    #: within ``seated.head_depth_m`` of its top (and ``head_separation_m`` of the highest
    #: point on the floor) span at most this (m). The flat top of a cupboard, a door or a wall
    #: piece is wider. 0: off.
    head_max_width_m: float = 0.35
    #: A floor from the robot's transforms (``detect(floor=...)``) is refined on the depth only
    #: this far (deg, m); a refinement that strays further is dropped for the given floor.
    floor_max_deg: float = 3.0
    floor_max_m: float = 0.1
    #: Seated people among what the standing rule leaves (:mod:`services.detector.core.seated`).
    seated: SeatedParams = field(default_factory=SeatedParams)
    hog_confirm: bool = False
    hog_min_score: float = 0.5

    def __post_init__(self) -> None:
        if not 0 < self.min_height_m < self.max_height_m:
            raise DetectorError(f"depth: need 0 < min_height_m < max_height_m, got {self.min_height_m}, {self.max_height_m}")
        if self.voxel_m <= 0 or self.cluster_tolerance_m <= 0 or self.pixel_step < 1:
            raise DetectorError("depth: voxel_m and cluster_tolerance_m must be > 0 and pixel_step >= 1")
