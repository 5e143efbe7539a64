"""A pydantic field type for numpy arrays with a fixed dtype and a checked shape.

On the Python side the field holds a C-contiguous ``np.ndarray``. The codec sends it as
raw bytes plus dtype and shape (never as lists of numbers); JSON dumps (schema files,
debug output) turn it into nested lists.

Usage::

    cov: NDArray(np.float64, (3, 3))      # exact shape
    vectors: NDArray(np.float32, (None, None))  # any N x D
"""

from __future__ import annotations

from typing import Annotated, Any, Sequence

import numpy as np
from pydantic import PlainSerializer, PlainValidator, WithJsonSchema

# Key names of an array passed as a mapping, e.g. from a JSON file or an old decoder.
_WIRE_KEYS = ("dtype", "shape", "data")


def _describe(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("N" if d is None else str(d) for d in shape) + ")"


def coerce_array(value: Any, dtype: np.dtype[Any], shape: Sequence[int | None]) -> np.ndarray:
    """Turn ``value`` into a contiguous array of ``dtype`` whose shape matches ``shape``.

    ``None`` in ``shape`` accepts any length on that axis. Accepts arrays, nested
    sequences, and ``{"dtype", "shape", "data"}`` mappings. Raises ``ValueError`` with a
    description of what was expected.
    """
    if isinstance(value, dict) and all(k in value for k in _WIRE_KEYS):
        src_dtype = np.dtype(value["dtype"])
        arr = np.frombuffer(value["data"], dtype=src_dtype).reshape(tuple(value["shape"]))
    elif isinstance(value, np.ndarray):
        arr = value
    elif isinstance(value, (list, tuple)):
        arr = np.asarray(value)
    else:
        raise ValueError(f"expected an array {_describe(shape)}, got {type(value).__name__}")
    if arr.dtype != dtype:
        if arr.dtype.kind not in "biuf" or (arr.size and arr.dtype.kind == "f" and dtype.kind in "iu"):
            raise ValueError(f"expected dtype {dtype.name}, got {arr.dtype.name}")
        arr = arr.astype(dtype)
    if arr.ndim != len(shape) or any(want is not None and got != want for got, want in zip(arr.shape, shape)):
        raise ValueError(f"expected shape {_describe(shape)}, got {tuple(arr.shape)}")
    return np.ascontiguousarray(arr)


def NDArray(dtype: Any, shape: Sequence[int | None]) -> Any:  # noqa: N802 - reads like a type
    """An annotated ``np.ndarray`` field type with the given dtype and shape."""
    dt = np.dtype(dtype)
    shp = tuple(shape)
    item_schema: dict[str, Any] = {"type": "number"} if dt.kind == "f" else {"type": "integer"}
    json_schema: dict[str, Any] = item_schema
    for dim in reversed(shp):
        json_schema = {"type": "array", "items": json_schema}
        if dim is not None:
            json_schema["minItems"] = json_schema["maxItems"] = dim
    json_schema = {**json_schema, "description": f"{dt.name} array of shape {_describe(shp)}"}
    return Annotated[
        np.ndarray,
        PlainValidator(lambda v: coerce_array(v, dt, shp)),
        PlainSerializer(lambda a: a.tolist(), when_used="json"),
        WithJsonSchema(json_schema),
    ]


def arrays_equal(a: Any, b: Any) -> bool:
    """Deep equality that treats numpy arrays by value (NaN equal to NaN)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a_arr, b_arr = np.asarray(a), np.asarray(b)
        return (
            a_arr.shape == b_arr.shape
            and a_arr.dtype == b_arr.dtype
            and bool(np.array_equal(a_arr, b_arr, equal_nan=a_arr.dtype.kind == "f"))
        )
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(arrays_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(arrays_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True
    return bool(a == b)
