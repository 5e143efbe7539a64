"""PETS09-S2L1 (``pets09_dev``) with the ground truth's boxes as the detections: the tracker
alone, with perfect detections, for ``benchmarks/quality.py --only pets-gt``.

Every ground-truth box of a frame (``gt.txt``, ``conf`` 1 and 0 rows alike: a perfect
detector also sees the people the judge does not count, who are then don't-care) is
scaled to the 480x360 frames (x 0.625), cropped and described by the project's colour
embedder, and placed on the ground plane as the whole chain places a HOG box: its foot
point (bottom centre) through ``ground_homography.json``, at z = 0.9 m. Every detection
scores 1. The same positions go to every tracker, with and without appearance, so what
appearance adds (or costs) is the only difference between those rows.

The crops' descriptors are cached under the cache folder, keyed by the embedder's code
and settings, the ground truth, the homography and the frames.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

import numpy as np

from benchmarks.quality_sim import hash_code
from services.localizer.core import FloorHomography, foot_points
from services.tracker.offline import Detections

__all__ = ["GT_SCALE", "PERSON_Z", "load_detections", "pets_gt_detections", "store_detections"]

ROOT = Path(__file__).resolve().parents[1]
GT_SCALE = 0.625  # gt.txt boxes are in 768x576 pixels, the frames 480x360
PERSON_Z = 0.9  # the data README: a box becomes a 3-D person at (x, y, 0.9)
FPS = 10.0
CODE = ("services/embedder/core", "services/embedder/config.py", "services/localizer/core/floor.py",
        "services/localizer/core/homography.py", "benchmarks/pets_gt.py")


def _gt_rows(root: Path) -> np.ndarray:
    gt = np.loadtxt(root / "gt.txt", delimiter=",", ndmin=2)
    n_frames = len(list((root / "frames").glob("frame_*.jpg")))
    gt = gt[gt[:, 0] <= n_frames]
    return gt[np.lexsort((gt[:, 1], gt[:, 0]))]


def cache_key(root: Path) -> str:
    """Hash of the embedder's settings and code, the ground truth, the homography and the frames."""
    import cv2

    from services.embedder.config import EmbedderConfig

    frames = sorted((root / "frames").glob("frame_*.jpg"))
    desc = {"version": 1, "code": hash_code(CODE), "embedder": EmbedderConfig().model_dump(mode="json"),
            "gt": hashlib.sha256((root / "gt.txt").read_bytes()).hexdigest(),
            "homography": json.loads((root / "ground_homography.json").read_text())["H"],
            "frames": [(p.name, p.stat().st_size) for p in frames], "opencv": cv2.__version__}
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:16]


def describe(root: Path) -> Detections:
    """The ground truth's boxes of every frame as detections with colour descriptors (~30 s);
    ``scores`` says which boxes the judge counts (1: ``conf`` 1, 0: ``conf`` 0)."""
    import cv2

    from services.embedder.config import EmbedderConfig, build_backend
    from services.embedder.core.backend import crop_boxes

    embedder = build_backend(EmbedderConfig())
    H = np.asarray(json.loads((root / "ground_homography.json").read_text())["H"], np.float64)
    gt = _gt_rows(root)
    frames, pos, descs, care = [], [], [], []
    for frame in np.unique(gt[:, 0]).astype(int).tolist():
        rows = gt[gt[:, 0] == frame]
        bgr = cv2.imread(str(root / "frames" / f"frame_{frame:04d}.jpg"))
        if bgr is None:
            raise OSError(f"cannot read frame {frame} of {root}")
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        x, y, w, h = (rows[:, k] * GT_SCALE for k in (2, 3, 4, 5))
        boxes = np.column_stack([x, y, x + w, y + h])
        crops, kept = crop_boxes(rgb, boxes)
        if not len(kept):
            continue
        pixels, _ = foot_points(boxes[kept])
        ground = FloorHomography(H).to_floor(pixels)[0]
        frames.append(np.full(len(kept), frame, np.int64))
        pos.append(np.column_stack([ground, np.full(len(kept), PERSON_Z)]))
        descs.append(np.asarray(embedder.embed(crops), np.float32))
        care.append(rows[kept, 6] > 0)
    f = np.concatenate(frames)
    return Detections(f, (f - 1) / FPS, np.concatenate(pos), np.concatenate(care).astype(np.float64),
                      np.concatenate(descs))


def pets_gt_detections(root: Path, cache_dir: Path, log: Callable[[str], None] = print,
                       care_only: bool = False) -> Detections:
    """:func:`describe`, from the cache when its key matches; every score 1. ``care_only``: the
    ``conf`` 1 boxes only (the people the judge counts)."""
    path = cache_dir / f"pets09_dev_gtboxes_colour_{cache_key(root)}.npz"
    if path.is_file():
        dets = load_detections(path)
    else:
        log("  pets09 (ground-truth boxes): describing the crops (first run; cached afterwards)")
        dets = store_detections(describe(root), path)
    keep = dets.scores > 0 if care_only else np.ones(len(dets.frames), bool)
    assert dets.descriptors is not None
    return Detections(dets.frames[keep], dets.stamps[keep], dets.positions[keep], np.ones(int(keep.sum())),
                      dets.descriptors[keep])


def load_detections(path: Path) -> Detections:
    """Detections with descriptors cached by :func:`store_detections`."""
    with np.load(path) as z:
        return Detections(z["frames"], z["stamps"], z["positions"], z["scores"], z["descriptors"])


def store_detections(dets: Detections, path: Path) -> Detections:
    """Cache ``dets`` at ``path`` (``.npz``, written whole then renamed); returns them."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, frames=dets.frames, stamps=dets.stamps, positions=dets.positions, scores=dets.scores,
                        descriptors=dets.descriptors)
    tmp.replace(path)
    return dets
