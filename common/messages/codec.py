"""msgpack wire format of the perception messages.

A payload is one msgpack map ``{"schema": NAME, "version": V, "body": {...}}``. The body
is the model's fields; numpy arrays inside it are msgpack extension type 1 holding
``dtype`` and ``shape`` followed by the raw little-endian bytes, and images hold their
pixels as one ``bin`` value. Nothing is ever sent as lists of numbers.

``decode`` never raises anything but :class:`DecodeError`, whatever the bytes.
"""

from __future__ import annotations

import math
import re
import struct
import threading
from typing import Any, TypeVar

import msgpack
import numpy as np
from pydantic import ValidationError

from common.messages.schemas import MESSAGE_TYPES, Message

__all__ = ["DEFAULT_MAX_BYTES", "DecodeError", "decode", "decode_any", "encode", "peek_schema", "unpack_unchecked"]

M = TypeVar("M", bound=Message)

#: Default size limit of a payload: a 1920x1080 RGB-D frame with float depth is ~14 MB.
DEFAULT_MAX_BYTES = 64 * 1024 * 1024

_EXT_NDARRAY = 1
_ARRAY_HEAD = struct.Struct("<BB")  # len(dtype string), ndim
_MAX_NDIM = 8
#: the shape of an array of each allowed number of dimensions, as little-endian uint64s
_SHAPES = [struct.Struct(f"<{n}Q") for n in range(_MAX_NDIM + 1)]
_DTYPE_RE = re.compile(r"[<>|=]?(b1|[iu][1248]|f[248])")
#: dtypes already read, by their bytes in the array header (only ones the pattern allows)
_DTYPES: dict[bytes, np.dtype[Any]] = {}
_local = threading.local()


class DecodeError(ValueError):
    """A payload that is not a valid message of the expected schema.

    ``field`` names the offending field (dotted path) when one is to blame; ``reason``
    says what is wrong.
    """

    def __init__(self, reason: str, *, schema: str = "", field: str = "") -> None:
        self.reason = reason
        self.schema = schema
        self.field = field
        where = ".".join(p for p in (schema, field) if p)
        super().__init__(f"{where}: {reason}" if where else reason)


def _pack_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        arr = obj if obj.dtype.byteorder in "=|<" else obj.astype(obj.dtype.newbyteorder("<"))
        if arr.dtype.hasobject:
            raise TypeError("object arrays cannot be encoded")
        dtype = arr.dtype.str.encode()
        head = _ARRAY_HEAD.pack(len(dtype), arr.ndim) + dtype + struct.pack(f"<{arr.ndim}Q", *arr.shape)
        return msgpack.ExtType(_EXT_NDARRAY, head + np.ascontiguousarray(arr).tobytes())
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot encode {type(obj).__name__}")


def _unpack_ext(code: int, data: bytes) -> Any:
    if code != _EXT_NDARRAY:
        raise ValueError(f"unknown msgpack extension type {code}")
    if len(data) < _ARRAY_HEAD.size:
        raise ValueError("truncated array header")
    dlen, ndim = _ARRAY_HEAD.unpack_from(data)
    if ndim > _MAX_NDIM:
        raise ValueError(f"array with {ndim} dimensions")
    off = _ARRAY_HEAD.size
    dtype_bytes = bytes(data[off : off + dlen])
    dtype = _DTYPES.get(dtype_bytes)
    if dtype is None:
        dtype_str = dtype_bytes.decode("ascii")
        if not _DTYPE_RE.fullmatch(dtype_str):
            raise ValueError(f"array dtype {dtype_str!r} is not a plain numeric dtype")
        dtype = _DTYPES[dtype_bytes] = np.dtype(dtype_str)  # a small, closed set (the pattern's)
    off += dlen
    shape = _SHAPES[ndim].unpack_from(data, off)
    off += 8 * ndim
    count = math.prod(shape)
    if count * dtype.itemsize != len(data) - off:
        raise ValueError(f"array of shape {shape} and dtype {dtype} does not match its {len(data) - off} bytes")
    return np.frombuffer(data, dtype=dtype, offset=off).reshape(shape)


def _packer() -> msgpack.Packer:
    # One packer per thread: its buffer is reused, which avoids an mmap/munmap of a fresh
    # multi-MB buffer per frame (see ZENOH_NOTES, the allocation trap).
    packer = getattr(_local, "packer", None)
    if packer is None:
        packer = _local.packer = msgpack.Packer(default=_pack_default, use_bin_type=True, autoreset=True)
    return packer


def encode(msg: Message) -> bytes:
    """Serialise a message, schema name and version included."""
    if not msg.SCHEMA_NAME:
        raise TypeError(f"{type(msg).__name__} is not a registered message type")
    body = msg.model_dump(mode="python")
    return _packer().pack({"schema": msg.SCHEMA_NAME, "version": msg.SCHEMA_VERSION, "body": body})


def _unpack(data: bytes | bytearray | memoryview, max_bytes: int | None) -> tuple[str, int, Any]:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise DecodeError(f"payload must be bytes, got {type(data).__name__}")
    limit = DEFAULT_MAX_BYTES if max_bytes is None else max_bytes
    if len(data) > limit:
        raise DecodeError(f"payload of {len(data)} bytes exceeds the {limit}-byte limit")
    try:
        obj = msgpack.unpackb(data, ext_hook=_unpack_ext, raw=False, strict_map_key=True, use_list=True)
    except (msgpack.UnpackException, ValueError, TypeError, OverflowError, struct.error, RecursionError, UnicodeDecodeError) as exc:
        raise DecodeError(f"not a valid msgpack payload ({type(exc).__name__}: {exc})") from exc
    if not isinstance(obj, dict) or not {"schema", "version", "body"} <= obj.keys():
        raise DecodeError("not a perception message: the schema/version/body envelope is missing")
    name, version, body = obj["schema"], obj["version"], obj["body"]
    if not isinstance(name, str) or not isinstance(version, int) or isinstance(version, bool):
        raise DecodeError("envelope: schema must be a string and version an integer")
    if not isinstance(body, dict):
        raise DecodeError("envelope: body is not a map", schema=name)
    return name, version, body


def _validate(model: type[M], version: int, body: dict[str, Any]) -> M:
    if version != model.SCHEMA_VERSION:
        raise DecodeError(
            f"schema version {version} is not supported (this build reads version {model.SCHEMA_VERSION}); "
            "update the older side so both speak the same version",
            schema=model.SCHEMA_NAME,
        )
    try:
        return model.model_validate(body)
    except ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        field = ".".join(str(p) for p in err["loc"])
        raise DecodeError(err["msg"], schema=model.SCHEMA_NAME, field=field) from exc
    except (ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise DecodeError(f"{type(exc).__name__}: {exc}", schema=model.SCHEMA_NAME) from exc


def decode(model: type[M], data: bytes | bytearray | memoryview, *, max_bytes: int | None = None) -> M:
    """Parse a payload as ``model``; raises :class:`DecodeError` for anything else."""
    name, version, body = _unpack(data, max_bytes)
    if name != model.SCHEMA_NAME:
        raise DecodeError(f"expected schema {model.SCHEMA_NAME}, got {name!r}", schema=name)
    return _validate(model, version, body)


def decode_any(data: bytes | bytearray | memoryview, *, max_bytes: int | None = None) -> Message:
    """Parse a payload of any registered message type, chosen by its schema name."""
    name, version, body = _unpack(data, max_bytes)
    model = MESSAGE_TYPES.get(name)
    if model is None:
        raise DecodeError(f"unknown schema {name!r}; known: {', '.join(sorted(MESSAGE_TYPES))}")
    return _validate(model, version, body)


def unpack_unchecked(data: bytes | bytearray | memoryview, *, max_bytes: int | None = None) -> tuple[str, int, dict[str, Any]]:
    """``(schema name, version, body)`` of a payload, the body as plain values and arrays,
    not validated: for diagnosing a payload that :func:`decode` refuses. Raises
    :class:`DecodeError` only when the bytes are not a message envelope at all."""
    return _unpack(data, max_bytes)


def peek_schema(data: bytes | bytearray | memoryview, *, max_bytes: int | None = None) -> tuple[str, int]:
    """The ``(schema name, version)`` of a payload, without validating the body."""
    name, version, _ = _unpack(data, max_bytes)
    return name, version
