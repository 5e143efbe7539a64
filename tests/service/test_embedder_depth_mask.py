"""Depth cuts the background: the core mask, the descriptor with masks, the service's bad inputs."""

from __future__ import annotations

import time

import numpy as np
import pytest

from common.messages.schemas import Image, RGBDFrame
from services.embedder.config import EmbedderConfig
from services.embedder.core import ColourDescriptor
from services.embedder.core.colour import ColourParams
from services.embedder.core.depth_mask import DEPTH_MISSING, MASK_EMPTY, DepthMaskParams, apply_mask, depth_masks
from tests.fixtures.embedder_synthetic import Outfit, render_person
from tests.fixtures.embedder_scene import BOX_GREEN, BOX_RED, detections, frame, scene
from tests.helpers.embedder_rig import Rig

RED = Outfit(skin=(220, 180, 150), hair=(40, 30, 20), shirt=(200, 30, 30), trousers=(30, 40, 160))


def person_depth(h: int = 64, w: int = 32, person_m: float = 2.0, wall_m: float = 4.0) -> np.ndarray:
    """(h, w) uint16 mm: a wall at ``wall_m`` with a person (the middle half of the columns) at ``person_m``."""
    d = np.full((h, w), int(wall_m * 1000), np.uint16)
    d[:, w // 4:3 * w // 4] = int(person_m * 1000)
    return d


def test_mask_keeps_the_person_and_drops_the_wall() -> None:
    d = person_depth()
    d[0:4, 10:14] = 0  # hair without depth
    (mask,), (reason,) = depth_masks(d, [(0, 0, 32, 64)], DepthMaskParams())
    assert reason is None and mask is not None and mask.shape == (64, 32)
    assert np.all(mask[10:, 8:24] == 1.0) and np.all(mask[:, :8] == 0.0) and np.all(mask[:, 24:] == 0.0)
    assert np.all(mask[0:4, 10:14] == 0.5)  # unknown: half weight
    # float metres work the same, NaN is "no depth"
    f = d.astype(np.float32) / 1000
    f[d == 0] = np.nan
    (mask_f,), _ = depth_masks(f, [(0, 0, 32, 64)], DepthMaskParams())
    np.testing.assert_array_equal(mask, mask_f)


def test_no_depth_in_the_box_and_a_mask_that_keeps_nothing_give_no_mask() -> None:
    d = np.zeros((64, 64), np.uint16)
    d[0, 0:25] = 2000  # 25 valid pixels of 1024: enough to measure, too few to keep 5 % of the box
    masks, reasons = depth_masks(d, [(32, 0, 64, 32), (0, 0, 32, 32)], DepthMaskParams())
    assert masks == [None, None] and reasons == [DEPTH_MISSING, MASK_EMPTY]
    far = np.full((10, 10), 20_000, np.uint16)  # beyond max_depth_m: invalid
    assert depth_masks(far, [(0, 0, 10, 10)], DepthMaskParams())[1] == [DEPTH_MISSING]
    with pytest.raises(ValueError, match="percentile"):
        DepthMaskParams(percentile=120.0)


def test_masked_descriptor_ignores_a_changed_background() -> None:
    rng = np.random.default_rng(3)
    person = render_person(RED, rng, size=(128, 64))
    a, b = np.full((128, 96, 3), (40, 160, 40), np.uint8), np.full((128, 96, 3), (200, 200, 40), np.uint8)
    a[:, 16:80], b[:, 16:80] = person, person
    mask = np.zeros((128, 96), np.float32)
    mask[:, 16:80] = 1.0
    # The grey-world white balance looks at the whole crop (the scene's light), so a background
    # change still moves the masked descriptor a little; without it the mask removes most of it.
    for params, ratio in ((ColourParams(), 0.95), (ColourParams(white_balance="none"), 0.5)):
        d = ColourDescriptor(params)
        plain = d.embed([a, b])
        masked = d.embed([a, b], masks=[mask, mask])
        assert np.linalg.norm(masked[0] - masked[1]) < ratio * np.linalg.norm(plain[0] - plain[1])
    desc = ColourDescriptor()
    np.testing.assert_allclose(desc.embed([a], masks=[None]), desc.embed([a]), atol=1e-6)
    # a mask with (almost) nothing in it falls back to the unmasked crop
    np.testing.assert_allclose(desc.embed([a], masks=[np.zeros((128, 96))]), desc.embed([a]), atol=1e-6)
    with pytest.raises(ValueError, match="masks"):
        desc.embed([a, b], masks=[mask])
    grey = apply_mask(a, mask)
    assert np.all(grey[:, 0] == 128) and np.array_equal(grey[:, 16:80], person)


def rgbd_frame(seq: int, stamp_ns: int, depth: np.ndarray) -> RGBDFrame:
    f = frame(seq, stamp_ns)
    return f.model_copy(update={"depth": Image.from_array(depth, "16UC1", f.header)})


def scene_depth() -> np.ndarray:
    """Depth of :func:`scene`: a wall at 5 m, the red person at 2 m, the green one at 3 m."""
    d = np.full((160, 240), 5000, np.uint16)
    d[10:138, 36:68] = 2000
    d[20:148, 166:198] = 3000
    return d


def test_service_masks_crops_when_the_frame_has_depth() -> None:
    rig = Rig()
    f = rgbd_frame(1, 1_000_000_000, scene_depth())
    rig.frames.put(f)
    rig.dets.put(detections(f, [BOX_RED, BOX_GREEN]))
    rig.service.poll(time.monotonic())
    (msg,) = rig.received()
    assert rig.counters.extra["masked_crops"] == 2
    unmasked = ColourDescriptor().embed([scene(1)[10:138, 20:84], scene(1)[20:148, 150:214]])
    assert not np.allclose(msg.vectors, unmasked, atol=1e-3)
    # turned off: the crops are described unmasked
    off = Rig(EmbedderConfig.model_validate({"depth_mask": {"enabled": False}}))
    off.frames.put(f)
    off.dets.put(detections(f, [BOX_RED, BOX_GREEN]))
    off.service.poll(time.monotonic())
    (plain,) = off.received()
    np.testing.assert_allclose(plain.vectors, unmasked, atol=1e-6)
    assert "masked_crops" not in off.counters.extra


def test_service_counts_each_bad_input() -> None:
    rig = Rig()
    depth = scene_depth()
    depth[20:148, 150:214] = 0       # no depth at all in the green person's box
    depth[100:160, 100:140] = 0      # a box with only a few valid pixels ...
    depth[100, 100:125] = 2500       # ... 25 of 2,400: measured, but the mask would keep ~1 %
    f = rgbd_frame(2, 2_000_000_000, depth)
    rig.frames.put(f)
    boxes = [BOX_RED, BOX_GREEN, (100.0, 100.0, 140.0, 160.0), (10.0, 10.0, 12.0, 30.0), (-30.0, 10.0, 40.0, 138.0),
             (300.0, 0.0, 400.0, 100.0)]
    rig.dets.put(detections(f, boxes))
    rig.service.poll(time.monotonic())
    (msg,) = rig.received()
    c = rig.counters.extra
    assert msg.indices.tolist() == [0, 1, 2, 4]          # the tiny box (3) and the one outside (5) are not described
    assert c["tiny_crops"] == 1 and c["empty_boxes"] == 1
    assert c["clipped_boxes"] == 1                        # partly outside: cut to the image and described
    assert c["depth_missing"] == 1 and c["mask_empty"] == 1
    assert c["masked_crops"] == 2                         # the red person and the clipped box
    assert np.all(np.isfinite(msg.vectors))
    # the box without depth is described exactly as without a depth image
    np.testing.assert_allclose(msg.vectors[1], ColourDescriptor().embed([scene(2)[20:148, 150:214]])[0], atol=1e-6)


def test_service_without_depth_describes_unmasked() -> None:
    rig = Rig()
    f = frame(3, 3_000_000_000)
    rig.frames.put(f)
    rig.dets.put(detections(f, [BOX_RED]))
    rig.service.poll(time.monotonic())
    (msg,) = rig.received()
    np.testing.assert_allclose(msg.vectors, ColourDescriptor().embed([scene(3)[10:138, 20:84]]), atol=1e-6)
    assert "masked_crops" not in rig.counters.extra and "depth_missing" not in rig.counters.extra
