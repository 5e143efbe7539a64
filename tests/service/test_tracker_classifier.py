"""Basso/Munaro's online per-track classifiers: learning, the association cue, ID recovery
after a full occlusion, and what a person alone in view does not teach."""

from __future__ import annotations

import numpy as np
import pytest

from services.tracker.config import TrackerConfig
from services.tracker.core.cues import classifier as clf
from services.tracker.core.cues.classifier import ClassifierParams
from services.tracker.core.recovery import RecoveryParams
from services.tracker.core.robust import AppearanceModel, RobustParams, RobustTracker
from services.tracker.core.types import FrameInput

COLOUR = AppearanceModel(0.35, 0.85, 0.40)


def unit(*v: float) -> np.ndarray:
    a = np.asarray(v, np.float32)
    return a / np.linalg.norm(a)


# Two people in similar clothes: they share feature 0, and differ in features 1 and 2.
A = unit(1, 1, 0, 0, 0, 0, 0, 0)
B = unit(1, 0, 1, 0, 0, 0, 0, 0)
# A again under other light: far from A's gallery (0.77 > t_recover), yet still "not B".
A_RELIT = unit(1, 1, 0, 0, 1, 1, 0, 0)


def test_untrained_classifier_says_nothing_and_one_descriptor_teaches_nothing() -> None:
    w = np.zeros((1, 9))
    assert np.all(clf.scores(w, clf.normalise(A[None]), 4.0) == 0.0)
    assert np.array_equal(clf.train(w, clf.normalise(A[None]), np.array([0]), ClassifierParams()), w)


def test_training_separates_a_person_from_the_others_in_view() -> None:
    rng = np.random.default_rng(0)
    w = np.zeros((2, 9))  # classifier 0 is A's, classifier 1 is B's
    for _ in range(30):
        u = clf.normalise(np.stack([A, B]) + rng.normal(scale=0.02, size=(2, 8)))
        w = clf.train(w, u, np.array([0, 1]), ClassifierParams())
    s = clf.scores(w, clf.normalise(np.stack([A, B, A_RELIT])), 4.0)
    assert s[0, 0] > 2 and s[1, 0] < -2 and s[0, 1] < -2 and s[1, 1] > 2
    assert s[2, 0] > 1 > -1 > s[2, 1]  # the relit view still reads as A, not B
    # the L2 decay keeps the weights bounded however long they train
    for _ in range(2000):
        w = clf.train(w, clf.normalise(np.stack([A, B])), np.array([0, 1]), ClassifierParams())
    assert np.all(np.abs(w) < 50)


def _frames(trk: RobustTracker, t0: float, t1: float, people: list[tuple[np.ndarray, float]]) -> float:
    t = t0
    while t < t1:
        pos = np.array([[x, 0.0, 1.0] for _, x in people]).reshape(-1, 3)
        d = np.stack([v for v, _ in people]) if people else None
        trk.step(t, FrameInput.of(pos, d))
        t = round(t + 0.1, 6)
    return t


def _id_at(trk: RobustTracker, x: float) -> int:
    return next(t.id for t in trk.tracks if abs(t.mean[0] - x) < 0.5)


@pytest.mark.parametrize("enabled", [True, False])
def test_a_person_who_returns_relit_after_a_full_occlusion_gets_their_id_back(enabled: bool) -> None:
    # a home, where most people confirmed are people coming back (p_new 0.3): the classifier's
    # log-odds then tip the open-set decision (core/recovery.py) that the gallery's distance alone
    # loses (with the online prior, after two newcomers, neither would give A's ID back)
    params = RobustParams(appearance=COLOUR, classifier=ClassifierParams() if enabled else None, max_coast_s=1.0,
                          recovery=RecoveryParams(p_new=0.3))
    trk = RobustTracker(params)
    t = _frames(trk, 0.0, 5.0, [(A, 0.0), (B, 3.0)])
    a_id, b_id = _id_at(trk, 0.0), _id_at(trk, 3.0)
    assert trk.tracks[0].clf_steps > 40 if enabled else trk.tracks[0].clf is None
    t = _frames(trk, t, t + 2.0, [(B, 3.0)])  # A leaves: their track ends, its classifier is remembered
    assert a_id not in trk.live_ids() and (a_id in trk.classifiers) == enabled
    _frames(trk, t, t + 1.0, [(A_RELIT, -2.0), (B, 3.0)])  # A comes back elsewhere, under other light
    back = _id_at(trk, -2.0)
    assert _id_at(trk, 3.0) == b_id
    if enabled:
        assert back == a_id  # the classifier recognised what the gallery's distance could not
    else:
        assert back not in (a_id, b_id)  # the gallery alone gives a new ID


def test_a_person_alone_in_view_trains_no_classifier() -> None:
    trk = RobustTracker(RobustParams(appearance=COLOUR))
    _frames(trk, 0.0, 2.0, [(A, 0.0)])
    assert [t.clf_steps for t in trk.tracks] == [0]


def test_a_forgotten_person_live_track_learns_no_classifier_and_none_is_kept() -> None:
    """perception forget on a person in view: their track keeps its ID but learns no appearance
    from then on, so nothing of them goes to the memory file or the ID memory when they leave."""
    trk = RobustTracker(RobustParams(appearance=COLOUR, max_coast_s=1.0))
    t = _frames(trk, 0.0, 3.0, [(A, 0.0), (B, 3.0)])
    a_id, b_id = _id_at(trk, 0.0), _id_at(trk, 3.0)
    assert a_id in trk.export_memory().classifiers
    done = trk.forget(a_id)
    assert done["live_track"] and done["classifier"]
    t = _frames(trk, t, t + 3.0, [(A, 0.0), (B, 3.0)])  # A stays in view beside B
    assert a_id in trk.live_ids() and _id_at(trk, 0.0) == a_id
    assert a_id not in trk.export_memory().classifiers and b_id in trk.export_memory().classifiers
    _frames(trk, t, t + 2.0, [(B, 3.0)])  # A leaves: nothing of them is remembered
    assert a_id not in trk.classifiers and a_id not in trk.memory


def test_snapshot_and_restore_keep_the_remembered_classifiers() -> None:
    trk = RobustTracker(RobustParams(appearance=COLOUR, max_coast_s=1.0))
    t = _frames(trk, 0.0, 3.0, [(A, 0.0), (B, 3.0)])
    _frames(trk, t, t + 2.0, [])
    state = trk.snapshot()
    remembered = dict(trk.classifiers)
    assert remembered
    trk.classifiers.clear()
    trk.restore(state)
    assert trk.classifiers.keys() == remembered.keys()


def test_config_turns_the_classifiers_off_and_validates() -> None:
    on = TrackerConfig().robust.params(COLOUR, 500)
    assert on.classifier == ClassifierParams()
    off = TrackerConfig.model_validate({"robust": {"classifier": {"enabled": False}}}).robust.params(COLOUR, 500)
    assert off.classifier is None
    with pytest.raises(ValueError):
        TrackerConfig.model_validate({"robust": {"classifier": {"rate": 0}}})


def test_classifiers_are_kept_in_the_id_memory_file_and_read_back_by_the_service(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from common.messages.keys import Keys
    from common.transport.memory import MemoryBus
    from services.tracker.core.identity import IdentityMemory
    from services.tracker.memory_file import read_classifiers, read_memory, save_memory
    from services.tracker.service import TrackerService

    memory = IdentityMemory(10)
    memory.archive(memory.new_id(), np.stack([A, A]))
    weights = {1: np.arange(9.0), 4: -np.arange(9.0)}
    path = tmp_path / "ids.npz"
    save_memory(path, memory, "colour", classifiers=weights)
    assert read_memory(path)[0].entries.keys() == {1}
    back = read_classifiers(path)
    assert back.keys() == {1, 4} and np.array_equal(back[4], weights[4])
    save_memory(path, memory, "colour")  # none to keep: an empty block
    assert read_classifiers(path) == {}
    with np.load(path) as f:  # a file written before classifiers existed reads as none
        np.savez(tmp_path / "old.npz", **{k: f[k] for k in f.files if not k.startswith("classifier")})
    assert read_classifiers(tmp_path / "old.npz") == {}
    with pytest.raises(ValueError, match="several dimensions"):
        save_memory(path, memory, "colour", classifiers={1: np.zeros(9), 2: np.zeros(5)})

    save_memory(path, memory, "colour", classifiers=weights)
    service = TrackerService(MemoryBus().transport(), Keys(robot="t"), TrackerConfig(memory_path=path))
    assert service.tracker.classifiers.keys() == {1, 4}  # type: ignore[union-attr]
    service.close()
    assert read_classifiers(path).keys() == {1, 4}  # written back at shutdown
