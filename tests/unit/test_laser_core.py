"""The laser's pure core: beams, segments, features, the boosted trees, legs and people."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from services.laser.core.boost import Boosted, BoostParams, train
from services.laser.core.features import LEIGH, MODEL, NAMES, features
from services.laser.core.legs import LegParams, Legs, detect, in_frame, pair
from services.laser.core.scan import ScanGeometry, beams
from services.laser.core.segments import segment
from services.laser.model_file import DEFAULT_MODEL, ModelFileError, load_model, write_model
from tools.simulator.core.laser_scan import LaserSpec, cast

SPEC = LaserSpec(sigma_m=0.0, dropout=0.0)
GEOM = ScanGeometry(float(SPEC.angles()[0]), float(np.radians(SPEC.step_deg)), SPEC.range_min, SPEC.range_max)


def _scan(circles: list[tuple[float, float, float]], rectangles: list[tuple[float, float, float, float]] = ()) -> np.ndarray:
    r = cast(np.zeros(2), 0.0, SPEC.angles(), np.asarray(rectangles, float).reshape(-1, 4),
             np.asarray(circles, float).reshape(-1, 3), SPEC.range_max)
    return np.where(np.isfinite(r), r, 0.0)


def test_beams_count_every_kind_of_no_return() -> None:
    g = ScanGeometry(-0.5, 0.25, 0.1, 5.0)
    b = beams(np.array([1.0, np.nan, np.inf, 0.0, 0.1, 5.0, 7.0, 2.0]), g)
    assert b.valid.tolist() == [True, False, False, False, False, False, False, True]
    assert b.invalid == {"nonfinite": 2, "too_near": 2, "too_far": 2}
    assert b.x[0] == pytest.approx(np.cos(-0.5)) and b.y[0] == pytest.approx(np.sin(-0.5))


@pytest.mark.parametrize("bad", [dict(angle_increment=0.0), dict(angle_increment=-0.1), dict(range_min=3.0, range_max=2.0)])
def test_a_bad_geometry_is_refused(bad: dict[str, float]) -> None:
    kw = dict(angle_min=0.0, angle_increment=0.1, range_min=0.1, range_max=5.0) | bad
    with pytest.raises(ValueError):
        ScanGeometry(**kw)


def test_segments_are_the_objects() -> None:
    # two legs 0.4 m apart and a wall behind them: three segments, ordered by their first beam
    r = _scan([(2.0, -0.2, 0.06), (2.0, 0.2, 0.06)], [(4.0, -3.0, 4.2, 3.0)])
    s = segment(beams(r, GEOM))
    assert len(s) >= 3
    firsts = [int(s.beams_of(k)[0]) for k in range(len(s))]
    assert firsts == sorted(firsts)
    # a segment's beams are increasing and every valid beam belongs to at most one segment
    assert len(set(s.order.tolist())) == len(s.order)
    for k in range(len(s)):
        assert np.all(np.diff(s.beams_of(k)) > 0)


def test_segments_join_across_a_nearer_object() -> None:
    # a thin post in front of a leg: the leg's points on both sides of the post are one segment
    r = _scan([(2.0, 0.0, 0.07), (1.0, 0.0, 0.005)])
    s = segment(beams(r, GEOM), min_points=1)
    sizes = sorted(len(s.beams_of(k)) for k in range(len(s)))
    assert len(s) == 2 and sizes[0] < sizes[1]


def test_too_few_points_are_no_segment() -> None:
    assert len(segment(beams(np.zeros(50), GEOM))) == 0
    r = np.zeros(SPEC.beams)
    r[100:102] = 2.0
    assert len(segment(beams(r, GEOM), min_points=3)) == 0


def test_features_of_a_circle() -> None:
    r = _scan([(2.0, 0.0, 0.06)])
    b = beams(r, GEOM)
    s = segment(b)
    x = features(b, s)
    assert x.shape == (1, len(NAMES)) and np.isfinite(x).all()
    f = dict(zip(NAMES, x[0]))
    assert f["distance"] == pytest.approx(1.94, abs=0.01)  # its near side
    assert f["circle_radius"] == pytest.approx(0.06, abs=0.005)
    assert f["width"] == pytest.approx(0.12, abs=0.02)
    assert f["circularity"] < 1e-4 and f["bulge"] > 0  # the middle is nearer than its ends
    assert f["occluded_left"] == 1.0 and f["occluded_right"] == 1.0  # nothing valid beside it
    # a flat wall: straight, no bulge
    b = beams(_scan([], [(3.0, -0.5, 3.2, 0.5)]), GEOM)
    f = dict(zip(NAMES, features(b, segment(b))[0]))
    assert f["linearity"] < 1e-6 and abs(f["bulge"]) < 1e-3


def test_the_vectorized_features_are_leigh_et_al_s() -> None:
    """Against a point-by-point port of their calcClusterFeatures (benchmarks/legs.py)."""
    from benchmarks.legs import forest_clusters

    rng = np.random.default_rng(3)
    r = _scan([(1.5, -0.4, 0.06), (1.7, -0.1, 0.07), (3.0, 1.0, 0.2)], [(5.0, -4.0, 5.3, 4.0)])
    r = np.where(r > 0, r + rng.normal(0, 0.004, r.shape), 0.0)
    b = beams(r, GEOM)
    ours = features(b, segment(b))[:, : len(LEIGH)]

    class Scan:
        ranges, angle_min, angle_increment = r, GEOM.angle_min, GEOM.angle_increment
        range_min, range_max = GEOM.range_min, GEOM.range_max

    theirs, _ = forest_clusters(Scan())
    assert ours.shape == theirs.shape
    np.testing.assert_allclose(ours, theirs, rtol=1e-6, atol=1e-9)


def _toy(n: int = 600, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    y = ((x[:, 0] + 0.5 * x[:, 1] ** 2 + 0.3 * rng.normal(size=n)) > 0.8).astype(float)
    return x, y


def test_boosted_trees_learn_and_are_calibrated() -> None:
    x, y = _toy()
    m = train(x, y, BoostParams(rounds=60))
    xt, yt = _toy(seed=1)
    p = m.probability(xt)
    assert np.mean((p > 0.5) == (yt > 0)) > 0.85
    # calibrated: the mean probability of each third is near its share of positives
    order = np.argsort(p)
    for part in np.array_split(order, 3):
        assert abs(p[part].mean() - yt[part].mean()) < 0.12


def test_training_is_deterministic_and_the_file_round_trips(tmp_path: Path) -> None:
    x, y = _toy()
    a, b = train(x, y, BoostParams(rounds=20)), train(x, y, BoostParams(rounds=20))
    assert json.dumps(a.to_json()) == json.dumps(b.to_json())
    m2 = Boosted.from_json(json.loads(json.dumps(a.to_json())))
    np.testing.assert_array_equal(m2.log_odds(x), a.log_odds(x))


def test_training_needs_both_classes() -> None:
    with pytest.raises(ValueError, match="both"):
        train(np.zeros((5, 2)), np.zeros(5))


def test_pairs_and_lone_legs() -> None:
    legs = Legs(np.array([[1.0, 0.0], [1.0, 0.3], [4.0, 0.0]]), np.array([0.9, 0.6, 0.7]), np.zeros(3), np.zeros(3))
    people = pair(legs)
    assert people.legs == [(0, 1), (2,)]
    np.testing.assert_allclose(people.xy, [[1.0, 0.15], [4.0, 0.0]])
    assert people.probability[0] == pytest.approx(1 - 0.1 * 0.4)
    # a lone leg's covariance is wider than a pair's; the pair's is longer along its legs
    assert np.linalg.det(people.cov[1]) > np.linalg.det(people.cov[0])
    assert people.cov[0][1, 1] > people.cov[0][0, 0]
    assert len(pair(Legs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0)))) == 0


def test_nearest_pairs_first() -> None:
    xy = np.array([[0.0, 0.0], [0.5, 0.0], [0.7, 0.0], [1.3, 0.0]])
    people = pair(Legs(xy, np.full(4, 0.8), np.zeros(4), np.zeros(4)), LegParams(pair_m=0.8))
    assert people.legs == [(0,), (1, 2), (3,)]


def test_people_in_the_map_frame() -> None:
    legs = Legs(np.array([[1.0, 0.0], [1.0, 0.2]]), np.array([0.9, 0.9]), np.zeros(2), np.zeros(2))
    people = pair(legs)
    yaw = np.pi / 2
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    pos, cov = in_frame(people, rot, np.array([5.0, 1.0, 0.3]), z=0.9, z_sigma=0.15)
    np.testing.assert_allclose(pos, [[5.0 - 0.1, 2.0, 0.9]], atol=1e-12)
    assert cov[0, 2, 2] == pytest.approx(0.0225) and cov[0, 0, 2] == 0.0
    assert cov[0, 0, 0] > cov[0, 1, 1]  # the legs' line, along y in the scanner, is along x in the map
    assert np.all(np.linalg.eigvalsh(cov[0]) > 0)


def test_the_shipped_model_finds_a_leg_and_not_a_wall() -> None:
    model, meta = load_model()
    assert meta["features"] == list(MODEL) and len(meta["data"]) == 4
    r = _scan([(2.0, -0.15, 0.06), (2.0, 0.15, 0.06)], [(4.0, -3.0, 4.2, 3.0)])
    legs = detect(r, GEOM, model, LegParams(min_probability=0.0))
    near = np.linalg.norm(legs.xy - [1.95, 0.0], axis=1) < 0.3
    assert near.sum() == 2 and legs.probability[near].min() > 0.5
    assert legs.probability[~near].max(initial=0.0) < 0.1  # the wall


def test_a_bad_model_file_names_the_fix(tmp_path: Path) -> None:
    with pytest.raises(ModelFileError, match="does not exist.*train-legs"):
        load_model(tmp_path / "none.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ModelFileError, match="not readable JSON"):
        load_model(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"format": "x"}')
    with pytest.raises(ModelFileError, match="not a leg model"):
        load_model(tmp_path / "other.json")
    model, meta = load_model(DEFAULT_MODEL)
    write_model(tmp_path / "old.json", model, {**meta, "features": ["n_points"]})
    with pytest.raises(ModelFileError, match="other features.*retrain"):
        load_model(tmp_path / "old.json")
