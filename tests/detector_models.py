"""Model files built by the detector tests and benchmark: ONNX graphs with known outputs, tiny Darknet nets.

Nothing here is a trained model; these files exercise parsing and decoding only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["constant_yolo_onnx", "tiny_darknet"]


def constant_yolo_onnx(path: Path, output: np.ndarray, input_hw: tuple[int | str, int | str] = (640, 640)) -> Path:
    """An ONNX model whose output is ``output`` (e.g. (1, 4+C, N)) whatever its (1, 3, H, W) input.

    The input still flows into the graph (times zero), so runtimes cannot prune it.
    """
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    out = np.asarray(output, np.float32)
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["mean"], axes=[1, 2, 3], keepdims=0),
        helper.make_node("Mul", ["mean", "zero"], ["nothing"]),
        helper.make_node("Add", ["table", "nothing"], ["output0"]),
    ]
    graph = helper.make_graph(
        nodes, "constant_yolo",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, *input_hw])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, list(out.shape))],
        initializer=[numpy_helper.from_array(out, "table"), numpy_helper.from_array(np.zeros(1, np.float32), "zero")],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    path.write_bytes(model.SerializeToString())
    return path


TINY_CFG = """[net]
width=32
height=32
channels=3

[convolutional]
batch_normalize=1
filters=4
size=3
stride=1
pad=1
activation=leaky

[maxpool]
size=8
stride=8

[convolutional]
size=1
stride=1
pad=1
filters={filters}
activation=linear

[yolo]
mask=0
anchors={anchor},{anchor}
classes={classes}
num=1
"""


def tiny_darknet(folder: Path, class_logits: list[float], objectness_logit: float = 4.0, anchor: int = 8,
                 seed: int = 0, truncate: bool = False) -> tuple[Path, Path]:
    """A 32x32-input YOLOv3-style net: a random BN conv, an 8x8 max-pool (4x4 grid), a 1x1 conv, one YOLO layer.

    The last conv has zero weights, so every grid cell outputs its biases: box offsets
    0 (centre of the cell), size ``anchor`` px, objectness ``sigmoid(objectness_logit)``
    and class scores ``sigmoid(class_logits)``. Returns (cfg, weights) paths.
    """
    classes = len(class_logits)
    filters = 5 + classes
    cfg = folder / "tiny.cfg"
    cfg.write_text(TINY_CFG.format(filters=filters, anchor=anchor, classes=classes))
    rng = np.random.default_rng(seed)
    first = np.concatenate([rng.normal(size=4) * 0.1, np.ones(4), np.zeros(4), np.ones(4), rng.normal(size=4 * 3 * 9) * 0.1])
    last = np.concatenate([[0.0, 0.0, 0.0, 0.0, objectness_logit, *class_logits], np.zeros(filters * 4)])
    header = np.array([0, 2, 0], np.int32).tobytes() + np.array([0], np.int64).tobytes()
    data = header + first.astype(np.float32).tobytes() + last.astype(np.float32).tobytes()
    weights = folder / "tiny.weights"
    weights.write_bytes(data[: len(data) // 2] if truncate else data)
    return cfg, weights
