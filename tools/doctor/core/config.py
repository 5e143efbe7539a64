"""Config: do the nodes agree on the camera, does the embedder's model card match a model
the tracker takes and has thresholds for, is the tracker's frame what arrives."""

from __future__ import annotations

from collections import Counter

from tools.doctor.core.facts import NODES, Check, Observation

__all__ = ["config_checks"]

SECTION = "Config"


def _settings(obs: Observation, service: str, name: str) -> list[str]:
    return sorted({n.settings[name] for n in obs.running(service) if n.settings.get(name)})


def _cameras(obs: Observation) -> Check:
    name = "camera names"
    chosen = {s: _settings(obs, s, "camera") for s in NODES}
    chosen = {s: [c for c in v if c != "*"] for s, v in chosen.items()}
    chosen = {s: v for s, v in chosen.items() if v}
    frames = sorted({k.split("/", 1)[1] for k, f in obs.streams.items() if k.startswith("frames/") and f.count})
    if not chosen:
        return Check(SECTION, name, "warn", "no node reports its settings", "run this project's version of every node")
    votes: Counter[str] = Counter(c for v in chosen.values() for c in v)
    votes.update(frames)
    common = votes.most_common(1)[0][0]
    odd = [s for s, v in chosen.items() if common not in v]
    figure = ", ".join(f"{s} {'/'.join(v)}" for s, v in chosen.items()) + (
        f"; frames on {', '.join(frames)}" if frames else "")
    if odd:
        return Check(SECTION, name, "fail", f"{figure}: the {' and '.join(odd)} use{'s' if len(odd) == 1 else ''} "
                     "another camera", f"set the {' and '.join(odd)}'s camera to {common} (--camera {common}, or "
                     f"camera: {common} in its config)")
    if frames and common not in frames:
        return Check(SECTION, name, "fail", f"{figure}: no frames on {common}",
                     f"publish the frames on frames/{common}, or set every node's camera to {frames[0]}")
    return Check(SECTION, name, "ok", figure)


def _embedding(obs: Observation) -> Check:
    name = "embedding model"
    cards = sorted(set(obs.cards))
    wanted = _settings(obs, "tracker", "embedding_model")
    locked = sorted({m for m in obs.track_models if m})
    known = set(",".join(_settings(obs, "tracker", "appearance")).split(",")) - {""}
    if not cards:
        return Check(SECTION, name, "warn", "no embeddings seen, so no model card to check", "see the embeddings line")
    card_names = sorted({c[0] for c in cards})
    figure = "; ".join(f"{n} ({d}-D, {m})" for n, d, m, _ in cards)
    if len(card_names) > 1:
        return Check(SECTION, name, "fail", f"{figure}: more than one model on one robot",
                     "run one embedding model: the tracker takes one and drops the others")
    card, _, _, has_thresholds = cards[0]
    takes = wanted or locked
    if takes and card not in takes:
        return Check(SECTION, name, "fail", f"the embedder sends {figure}, the tracker takes {'/'.join(takes)}",
                     f"set the tracker's embedding_model to {card} (or leave it unset), or run the embedder of "
                     f"{'/'.join(takes)}")
    dropped = sum(n.counters.get("dropped_wrong_model", 0) for n in obs.running("tracker"))
    if dropped:
        return Check(SECTION, name, "fail", f"{figure}: the tracker dropped {dropped:g} as another model's",
                     f"set the tracker's embedding_model to {card}, and run one embedding model")
    if known and card not in known:
        if has_thresholds:
            return Check(SECTION, name, "warn", f"{figure}: the tracker uses the thresholds of the model card",
                         f"calibrate thresholds for {card} (perception calibrate-embedder) into the tracker's appearance")
        return Check(SECTION, name, "fail", f"{figure}: the tracker has no thresholds for it ({', '.join(sorted(known))})",
                     f"add appearance: {{{card}: {{t_lower, t_upper, t_recover}}}} to the tracker's config "
                     "(perception calibrate-embedder)")
    where = "the tracker has thresholds for it" if card in known else "the tracker takes it"
    return Check(SECTION, name, "ok", f"{figure}; {where}")


def _tracker(obs: Observation) -> Check:
    name = "tracker settings"
    nodes = obs.running("tracker")
    if not nodes:
        return Check(SECTION, name, "warn", "no tracker to check", "see the tracker line")
    s = nodes[0].settings
    frame = s.get("frame_id", "map")
    figure = f"profile {s.get('profile', '?')}, frame {frame}, camera {s.get('camera', '?')}"
    arriving = sorted({f for f in obs.localized_frames if f})
    wrong = sum(n.counters.get("dropped_wrong_frame", 0) for n in nodes)
    target = _settings(obs, "localizer", "target_frame")
    if (arriving and frame not in arriving) or wrong or (target and frame not in target):
        what = "/".join(arriving or target)
        return Check(SECTION, name, "fail", f"{figure}, but the localized detections are in {what or 'another frame'}",
                     f"make the localizer's target_frame and the tracker's frame_id the same ({what or frame})")
    return Check(SECTION, name, "ok", figure)


def config_checks(obs: Observation) -> list[Check]:
    return [_cameras(obs), _embedding(obs), _tracker(obs)]
