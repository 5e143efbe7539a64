"""``perception embedder``: run the embedder node on one camera."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.embedder import flags
from services.embedder.config import EmbedderConfig
from services.embedder.service import EmbedderService

DESCRIPTION = """\
Describe the appearance of every detected person: pair each Detections message with
its RGB frame, crop the boxes and publish one descriptor per detection on
embeddings/{camera}, with a model card (name, dimension, metric, recommended tracker
thresholds).

Backends: 'colour' (default, no model: striped colour histograms, 224-D) and 'onnx'
(any Re-ID model: --model FILE.onnx; GPU via onnxruntime-gpu, providers TensorRT,
CUDA, CPU in that order unless --providers says otherwise).

Settings layer as defaults -> --service-config FILE (section 'embedder', or the whole
file) -> PERCEPTION_EMBEDDER__FIELD environment variables -> flags."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "embedder", EmbedderConfig, flags.overrides(args), EmbedderService, prepare=flags.prepare)
