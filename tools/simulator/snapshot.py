"""One frame as a picture: RGB and colourised depth side by side, for a person to look at."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from tools.simulator.core.render import DEPTH_MAX_M, RenderResult, default_camera
from tools.simulator.core.simulation import FrameData

__all__ = ["snapshot_image", "write_snapshot"]


def snapshot_image(fd: FrameData) -> np.ndarray:
    """(H, 2 W, 3) BGR uint8: the RGB frame, then depth (near blue .. far red, invalid black),
    each counted ground-truth person marked with its id at the torso centre. With cameras fixed
    on the base, (H (1 + views), 2 W, 3): their rows below the head camera's, each marking the
    people that camera counts."""
    rows = [_panel(fd.render, fd.map_camera, [p.counted for p in fd.people], fd, f"t={fd.t:.1f}s")]
    for name, view in fd.views.items():
        rows.append(_panel(view.render, view.map_camera, [bool(c) for c in view.counted], fd, name))
    return np.vstack(rows)


def _panel(render: RenderResult, map_camera: np.ndarray, counted: list[bool], fd: FrameData, label: str) -> np.ndarray:
    rgb = cv2.cvtColor(render.rgb, cv2.COLOR_RGB2BGR)
    depth = render.depth_mm.astype(np.float32) / 1000.0
    scaled = np.clip(depth / DEPTH_MAX_M * 255.0, 0, 255).astype(np.uint8)
    coloured = cv2.applyColorMap(scaled, cv2.COLORMAP_JET)
    coloured[render.depth_mm == 0] = 0
    cam_from_map = np.linalg.inv(map_camera)
    h, w = depth.shape
    scale = max(0.35, w / 1280.0)
    cam = default_camera(w, h)  # the simulator's camera (SimulatedStream)
    for p, seen in zip(fd.people, counted):
        c = cam_from_map @ np.append(p.position, 1.0)
        if not seen or c[2] <= 0.1:
            continue
        u, v = int(cam.fx * c[0] / c[2] + cam.cx), int(cam.fy * c[1] / c[2] + cam.cy)
        for img in (rgb, coloured):
            cv2.drawMarker(img, (u, v), (255, 255, 255), cv2.MARKER_CROSS, int(12 * scale * 2), 2)
            cv2.putText(img, str(p.id), (u + 6, v - 6), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 2)
    cv2.putText(rgb, label, (8, int(24 * scale * 2)), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 2)
    return np.hstack([rgb, coloured])


def write_snapshot(fd: FrameData, path: Path) -> None:
    """Write :func:`snapshot_image` to ``path`` (PNG or JPEG by extension)."""
    if not cv2.imwrite(str(path), snapshot_image(fd)):
        raise OSError(f"could not write {path}")
