"""What the 2-D laser adds, on the simulated apartment: every scenario through the in-process chain
(``tools.demo.inprocess.run_chain``) twice, with the simulator's base laser on both times and the
same ground truth (everyone the camera or the laser could see, all round the robot): the camera
alone (the tracker reads no laser) against the camera and the laser (the laser node's people fused
by the tracker). Reported per scenario: objects, MOTA, IDF1, ID switches, and the ID switches of
the person the robot guides or follows (ground-truth person 1 of ``guided-tour`` and
``people-following``: the one who must keep their ID).

    python benchmarks/quality_laser.py [--scenarios a,b] [--seconds S] [--json FILE]

``benchmarks/quality.py --only laser`` prints the same section.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.messages.schemas import PeopleGroundTruth, Tracks  # noqa: E402
from tools.demo.scoring import frame_outputs, nearest_pairs  # noqa: E402

#: the scenarios' person whose ID matters most: the one the robot guides or follows
FOLLOWED = {"guided-tour": 1, "people-following": 1}
FPS, SIZE, SEED = 10.0, (320, 240), 0


def person_switches(truth: dict[int, PeopleGroundTruth], tracks: list[Tracks], person: int, gate_m: float = 1.0,
                    source: str = "head") -> tuple[int, int, int]:
    """(ID switches, frames matched, frames counted) of ground-truth ``person`` over the frames they
    count in (camera or laser): each frame they are paired with the nearest reported track within
    ``gate_m`` on the floor that no nearer person took (greedy, nearest pairs first); a switch is
    a matched ID other than their previous matched one."""
    by_seq = {t.header.seq: t for t in frame_outputs(tracks, source)}
    switches = matched = counted = 0
    last: int | None = None
    for seq in sorted(truth):
        people = truth[seq].around()
        if not any(p.id == person for p in people):
            continue
        counted += 1
        out = by_seq.get(seq)
        for i, j in nearest_pairs(people, out.tracks, gate_m) if out is not None else []:
            if people[i].id == person:
                tid = out.tracks[j].id  # type: ignore[union-attr]
                matched += 1
                switches += int(last is not None and tid != last)
                last = tid
    return switches, matched, counted


def run(scenarios: list[str], seconds: float | None) -> list[dict[str, Any]]:
    """One row per scenario and mode (camera, camera+laser)."""
    from tools.demo.inprocess import run_chain
    from tools.simulator.core.scenarios import SCENARIOS

    rows = []
    for name in scenarios:
        duration = SCENARIOS[name].duration_s if seconds is None else seconds
        for fuse in (False, True):
            t0 = time.perf_counter()
            result = run_chain(name, duration_s=duration, fps=FPS, width=SIZE[0], height=SIZE[1], seed=SEED,
                               laser=True, fuse_laser=fuse)
            seq = result.report["sequences"][name]
            row: dict[str, Any] = {"scenario": name, "mode": "camera + laser" if fuse else "camera", "seconds": duration,
                                   **{k: seq[k] for k in ("objects", "matches", "misses", "false_positives",
                                                          "id_switches", "mota", "idf1")},
                                   "wall_s": round(time.perf_counter() - t0, 1)}
            if name in FOLLOWED:
                sw, matched, counted = person_switches(result.truth, result.tracks, FOLLOWED[name])
                row["followed"] = {"person": FOLLOWED[name], "id_switches": sw, "matched": matched, "counted": counted}
            rows.append(row)
    return rows


def format_rows(rows: list[dict[str, Any]]) -> str:
    head = (f"{'scenario':30} {'mode':15} {'objects':>7} {'misses':>6} {'FP':>4} {'IDSW':>4} {'MOTA':>6} {'IDF1':>6}"
            f"  followed person: IDSW, matched / counted")
    lines = ["Simulated apartment with the base laser (360 degrees, 15 Hz): the camera alone against the camera and "
             "the laser, judged over everyone the camera or the laser could see", head, "-" * len(head)]
    for r in rows:
        f = r.get("followed")
        extra = f"  {f['id_switches']}, {f['matched']} / {f['counted']}" if f else ""
        lines.append(f"{r['scenario']:30} {r['mode']:15} {r['objects']:7d} {r['misses']:6d} {r['false_positives']:4d} "
                     f"{r['id_switches']:4d} {r['mota']:6.3f} {r['idf1']:6.3f}{extra}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from tools.simulator.core.scenarios import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", type=lambda t: t.split(","), default=list(SCENARIOS), metavar="A,B",
                        help="scenarios to run (default all)")
    parser.add_argument("--seconds", type=float, default=None, metavar="S", help="simulated seconds (default: each "
                        "scenario's length)")
    parser.add_argument("--json", type=Path, default=None, metavar="FILE", help="also write the rows as JSON")
    args = parser.parse_args(argv)
    unknown = [s for s in args.scenarios if s not in SCENARIOS]
    if unknown:
        parser.error(f"unknown scenario {unknown[0]!r}; choose from {', '.join(SCENARIOS)}")
    rows = run(args.scenarios, args.seconds)
    print(format_rows(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
