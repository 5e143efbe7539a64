"""Small ONNX graphs built on the spot, for tests and benchmarks (needs the ``onnx`` package).

* :func:`projection_model`: (N, 3, H, W) -> Flatten -> MatMul(P) -> (N, D); with the
  identity as P the output is the preprocessed input itself, which lets a test check
  resize, channel order and normalisation exactly.
* :func:`conv_model`: a strided conv net of Re-ID size (about 0.6 GFLOP at 256 x 128,
  512-D output) with random weights, for timing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["conv_model", "projection_model", "rank3_model"]


def _save(graph: Any, path: str | Path) -> Path:
    import onnx
    from onnx import helper

    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return Path(path)


def projection_model(path: str | Path, height: int, width: int, projection: np.ndarray | None = None,
                     batch: int | str = "N") -> Path:
    """Write a Flatten + MatMul graph; ``projection`` is (3*H*W, D) float32 (identity if None)."""
    from onnx import TensorProto, helper, numpy_helper

    p = np.eye(3 * height * width, dtype=np.float32) if projection is None else projection.astype(np.float32)
    nodes = [helper.make_node("Flatten", ["input"], ["flat"], axis=1),
             helper.make_node("MatMul", ["flat", "P"], ["output"])]
    graph = helper.make_graph(
        nodes, "projection",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, [batch, 3, height, width])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, [batch, p.shape[1]])],
        [numpy_helper.from_array(p, "P")])
    return _save(graph, path)


def rank3_model(path: str | Path) -> Path:
    """A graph whose input is (N, 3, L): not an image model."""
    from onnx import TensorProto, helper

    graph = helper.make_graph(
        [helper.make_node("Flatten", ["input"], ["output"], axis=1)], "rank3",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, ["N", 3, 16])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, ["N", 48])])
    return _save(graph, path)


def conv_model(path: str | Path, height: int = 256, width: int = 128, dim: int = 512, seed: int = 0) -> Path:
    """A 6-stage conv net with random weights (stride 2 each stage), GAP and a linear layer."""
    from onnx import TensorProto, helper, numpy_helper

    rng = np.random.default_rng(seed)
    channels = [3, 32, 64, 96, 128, 256, 512]
    nodes, inits, x = [], [], "input"
    for i, (cin, cout) in enumerate(zip(channels[:-1], channels[1:], strict=True)):
        w = (rng.standard_normal((cout, cin, 3, 3)) * np.sqrt(2.0 / (cin * 9))).astype(np.float32)
        inits += [numpy_helper.from_array(w, f"w{i}"), numpy_helper.from_array(np.zeros(cout, np.float32), f"b{i}")]
        nodes.append(helper.make_node("Conv", [x, f"w{i}", f"b{i}"], [f"c{i}"], kernel_shape=[3, 3],
                                      pads=[1, 1, 1, 1], strides=[2, 2] if i < 5 else [1, 1]))
        nodes.append(helper.make_node("Relu", [f"c{i}"], [f"r{i}"]))
        x = f"r{i}"
        if i == 4:  # a second, unstrided conv at this resolution, as Re-ID backbones have
            w2 = (rng.standard_normal((cout, cout, 3, 3)) * np.sqrt(2.0 / (cout * 9))).astype(np.float32)
            inits.append(numpy_helper.from_array(w2, "w4b"))
            nodes += [helper.make_node("Conv", [x, "w4b"], ["c4b"], kernel_shape=[3, 3], pads=[1, 1, 1, 1]),
                      helper.make_node("Relu", ["c4b"], ["r4b"])]
            x = "r4b"
    fc = (rng.standard_normal((channels[-1], dim)) / np.sqrt(channels[-1])).astype(np.float32)
    inits.append(numpy_helper.from_array(fc, "fc"))
    nodes += [helper.make_node("GlobalAveragePool", [x], ["gap"]),
              helper.make_node("Flatten", ["gap"], ["flat"], axis=1),
              helper.make_node("MatMul", ["flat", "fc"], ["output"])]
    graph = helper.make_graph(
        nodes, "conv_reid",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, ["N", 3, height, width])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, ["N", dim])], inits)
    return _save(graph, path)
