"""The msgpack codec: round trips of every schema, typed errors, and fuzzing."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from common.messages.codec import DecodeError, decode, decode_any, encode, peek_schema
from common.messages.samples import example_messages
from common.messages.schemas import MESSAGE_TYPES, Detections, Embeddings, Image, Message, Tracks
from tests.fixtures.strategies import MESSAGE_STRATEGIES

EXAMPLES = example_messages()


def test_every_registered_schema_has_a_strategy_and_an_example() -> None:
    assert set(MESSAGE_STRATEGIES) == set(MESSAGE_TYPES)
    assert {m.SCHEMA_NAME for m in EXAMPLES} == set(MESSAGE_TYPES)


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: type(m).__name__)
def test_example_round_trip(msg: Message) -> None:
    data = encode(msg)
    assert decode(type(msg), data) == msg
    assert decode_any(data) == msg
    assert peek_schema(data) == (msg.SCHEMA_NAME, msg.SCHEMA_VERSION)


@pytest.mark.parametrize("name", sorted(MESSAGE_STRATEGIES))
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_property_round_trip(name: str, data: st.DataObject) -> None:
    msg = data.draw(MESSAGE_STRATEGIES[name])
    back = decode(MESSAGE_TYPES[name], encode(msg))
    assert back == msg
    assert encode(back) == encode(msg)


def test_arrays_travel_as_raw_bytes_not_lists() -> None:
    msg = next(m for m in EXAMPLES if isinstance(m, Embeddings))
    raw = msgpack.unpackb(encode(msg), raw=False, ext_hook=lambda code, data: (code, data))
    code, blob = raw["body"]["vectors"]
    assert code == 1 and len(blob) >= msg.vectors.nbytes
    img = next(m for m in EXAMPLES if isinstance(m, Image) and m.encoding == "rgb8")
    body = msgpack.unpackb(encode(img), raw=False)["body"]
    assert isinstance(body["data"], bytes) and body["shape"] == list(img.shape)


def test_decoded_arrays_have_declared_dtype_and_shape() -> None:
    msg = next(m for m in EXAMPLES if isinstance(m, Tracks))
    back = decode(Tracks, encode(msg))
    cov = back.tracks[0].covariance
    assert cov.dtype == np.float64 and cov.shape == (6, 6)


def _envelope(body: dict, name: str = "perception.Detections", version: int = 1) -> bytes:
    return msgpack.packb({"schema": name, "version": version, "body": body}, use_bin_type=True)


def test_wrong_version_is_refused_with_a_reason() -> None:
    good = msgpack.unpackb(encode(EXAMPLES[5]), raw=False)
    with pytest.raises(DecodeError, match="version 2 is not supported"):
        decode(Detections, _envelope(good["body"], version=2))


def test_wrong_schema_is_refused() -> None:
    with pytest.raises(DecodeError, match="expected schema perception.Tracks"):
        decode(Tracks, encode(EXAMPLES[5]))


def test_unknown_schema_is_refused_by_decode_any() -> None:
    with pytest.raises(DecodeError, match="unknown schema 'perception.Nope'"):
        decode_any(_envelope({}, name="perception.Nope"))


def test_error_names_the_field() -> None:
    body = msgpack.unpackb(encode(EXAMPLES[5]), raw=False)["body"]
    body["detections"][1]["score"] = 3.0
    with pytest.raises(DecodeError) as info:
        decode(Detections, _envelope(body))
    assert info.value.field == "detections.1.score"
    assert "perception.Detections.detections.1.score" in str(info.value)


def test_size_limit_is_enforced() -> None:
    data = encode(EXAMPLES[0])
    with pytest.raises(DecodeError, match="exceeds the 100-byte limit"):
        decode(Image, data, max_bytes=100)
    assert decode(Image, data, max_bytes=len(data)) == EXAMPLES[0]


def test_inconsistent_image_is_refused() -> None:
    body = msgpack.unpackb(encode(EXAMPLES[0]), raw=False)["body"]
    body["data"] = body["data"][:-1]
    with pytest.raises(DecodeError, match="data holds"):
        decode(Image, _envelope(body, name="perception.Image"))


def test_nan_position_is_refused() -> None:
    body = msgpack.unpackb(encode(EXAMPLES[6]), raw=False, ext_hook=lambda c, d: msgpack.ExtType(c, d))
    body["body"]["detections"][0]["position"] = [float("nan"), 0.0, 0.0]
    with pytest.raises(DecodeError, match="position must be finite"):
        decode_any(msgpack.packb(body, use_bin_type=True))


def test_non_bytes_payload_is_refused() -> None:
    with pytest.raises(DecodeError, match="payload must be bytes"):
        decode(Image, "text")  # type: ignore[arg-type]


# ------------------------------------------------------------------------- fuzzing


def _decode_only_typed_errors(data: bytes) -> None:
    """Decoding may succeed (a flip in a value) or raise DecodeError, nothing else."""
    for model in MESSAGE_TYPES.values():
        try:
            decode(model, data)
        except DecodeError:
            pass
    try:
        decode_any(data)
    except DecodeError:
        pass


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=512))
def test_fuzz_random_bytes(data: bytes) -> None:
    _decode_only_typed_errors(data)


@settings(max_examples=300, deadline=None)
@given(idx=st.integers(0, len(EXAMPLES) - 1), cut=st.floats(0, 1, exclude_max=True))
def test_fuzz_truncated(idx: int, cut: float) -> None:
    data = encode(EXAMPLES[idx])
    truncated = data[: int(len(data) * cut)]
    with pytest.raises(DecodeError):
        decode_any(truncated)


@settings(max_examples=500, deadline=None)
@given(idx=st.integers(0, len(EXAMPLES) - 1), flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 7)), min_size=1, max_size=4))
def test_fuzz_bit_flips(idx: int, flips: list[tuple[float, int]]) -> None:
    data = bytearray(encode(EXAMPLES[idx]))
    for pos, bit in flips:
        data[int(pos * len(data))] ^= 1 << bit
    _decode_only_typed_errors(bytes(data))


@settings(max_examples=200, deadline=None)
@given(version=st.integers(-(2**31), 2**31).filter(lambda v: v != 1), idx=st.integers(0, len(EXAMPLES) - 1))
def test_fuzz_wrong_version(version: int, idx: int) -> None:
    raw = msgpack.unpackb(encode(EXAMPLES[idx]), raw=False, ext_hook=lambda c, d: msgpack.ExtType(c, d))
    raw["version"] = version
    with pytest.raises(DecodeError, match="version"):
        decode_any(msgpack.packb(raw, use_bin_type=True))


@settings(max_examples=200, deadline=None)
@given(st.recursive(st.none() | st.booleans() | st.integers(-(2**63), 2**64 - 1) | st.floats() | st.text(max_size=5) | st.binary(max_size=5),
                    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=5), kids, max_size=4),
                    max_leaves=20),
       st.sampled_from(sorted(MESSAGE_TYPES)))
def test_fuzz_well_formed_msgpack_with_wrong_body(body: object, name: str) -> None:
    data = msgpack.packb({"schema": name, "version": 1, "body": body}, use_bin_type=True)
    with pytest.raises(DecodeError):
        decode(MESSAGE_TYPES[name], data)
