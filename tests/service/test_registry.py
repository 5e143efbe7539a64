"""The node registry (common/messages/registry.py) against what the nodes really do, and every list
derived from it or checked against it.

Each node is built on the in-memory transport, as ``run_node`` builds it, and what it
subscribes, publishes, serves and watches must be exactly what its registry entry declares
(over the configurations that switch its optional inputs on). Then the key table, the
certificate roles, the access-control grants, the command table, the demo's, viewer's and
doctor's stage lists and the import rules must agree with the registry.
"""

from __future__ import annotations

import configparser
import importlib
from pathlib import Path
from typing import Any

import pytest

from common.transport.acl import grants
from common.transport.certs import ROLES
from common.messages.keys import STREAMS, Keys
from common.transport.memory import MemoryBus, key_matches, keys_intersect
from common.messages.registry import NODES, NodeEntry, node, stages
from common.runtime.service import Counters

ROOT = Path(__file__).resolve().parents[2]
KEYS = Keys(robot="robot-name")

#: Settings per node beyond the defaults: no file in the user's state directory, and the
#: configurations that switch a node's optional inputs on (the depth detector's floor from tf).
CONFIGS: dict[str, list[dict[str, Any]]] = {
    "tracker": [{"memory_path": None}],
    "detector": [{}, {"backend": "depth", "floor_frame": "base_footprint"}],
    "viewer": [{"port": 0}],
    # a folder of one image (made by the fixture: FOLDER), played in real time and paced by the detector
    "camera": [{"source": "FOLDER"}, {"source": "FOLDER", "pace": "max"}],
}


def _load(spec: str) -> Any:
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def _streams_of(keys: list[str]) -> set[str]:
    """The stream names of concrete keys or key expressions (keys outside the project's base,
    ROS 2's, are left out: see test_only_a_ros2_node_speaks_ros2)."""
    out = set()
    for key in keys:
        if not key.startswith(KEYS.base + "/"):
            continue
        names = {s.name for s in STREAMS if keys_intersect(KEYS.pattern(s.name), key)}
        assert len(names) == 1, f"{key} matches streams {names}"
        out |= names
    return out


def _build(entry: NodeEntry, settings: dict[str, Any]) -> dict[str, set[str]]:
    bus = MemoryBus()
    transport = bus.transport()
    config = _load(entry.config)(**settings)
    built = _load(entry.node)(transport, KEYS, config, Counters())
    try:
        return {
            "subscribes": _streams_of([s.key for s in built.io.subscriptions]),
            "publishes": _streams_of([p.key for p in built.io.publishers]),
            "serves": _streams_of([k for k, _ in bus.queryables]),
            "watches": _streams_of([k for k, _ in bus.watchers]),
            "keys": {"subscribes": [s.key for s in built.io.subscriptions], "publishes": [p.key for p in built.io.publishers],
                     "serves": [k for k, _ in bus.queryables], "watches": [k for k, _ in bus.watchers]},
            "tokens": list(bus.tokens),
        }
    finally:
        built.close()
        transport.close()


@pytest.fixture(scope="module")
def observed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[dict[str, Any]]]:
    import cv2
    import numpy as np

    folder = tmp_path_factory.mktemp("camera")
    cv2.imwrite(str(folder / "0001.png"), np.zeros((48, 64, 3), np.uint8))

    def settings(s: dict[str, Any]) -> dict[str, Any]:
        return {k: str(folder) if v == "FOLDER" else v for k, v in s.items()}

    return {e.name: [_build(e, settings(s)) for s in CONFIGS.get(e.name, [{}])] for e in NODES}


@pytest.mark.parametrize("entry", NODES, ids=lambda e: e.name)
def test_a_node_does_what_its_entry_declares(entry: NodeEntry, observed: dict[str, list[dict[str, Any]]]) -> None:
    runs = observed[entry.name]
    for field in ("subscribes", "publishes", "serves", "watches"):
        seen = set().union(*(r[field] for r in runs))
        assert seen == set(getattr(entry, field)), (
            f"{entry.name} {field} {sorted(seen)} but common/messages/registry.py says {sorted(getattr(entry, field))}")


@pytest.mark.parametrize("entry", NODES, ids=lambda e: e.name)
def test_the_access_rules_let_a_node_do_what_it_does(entry: NodeEntry, observed: dict[str, list[dict[str, Any]]]) -> None:
    import zenoh

    grant = grants(domain=0)[entry.name]
    allowed = {"subscribes": grant.subscribe, "publishes": grant.publish, "serves": grant.serve, "watches": grant.watch,
               "tokens": grant.token}
    for run in observed[entry.name]:
        for field, keys in [*run["keys"].items(), ("tokens", run["tokens"])]:
            for key in keys:
                if key.startswith(KEYS.base + "/"):
                    ok = any(key_matches(p, key) for p in allowed[field])
                else:  # ROS 2 keys: Zenoh's own inclusion (sub-chunk wildcards, verbatim @ chunks)
                    ok = any(zenoh.KeyExpr(p).includes(zenoh.KeyExpr(key)) for p in allowed[field])
                assert ok, f"{entry.name} may not {field} {key}"
    # and nothing beyond its own streams, status and liveliness (and, for ROS 2, domain 0)
    ros = {"0/**", "0/**/@adv/**"} if entry.ros2 else set()
    assert set(grant.publish) == {KEYS.pattern(s) for s in entry.publishes} | {KEYS.status(entry.name, "*")} | ros


@pytest.mark.parametrize("entry", NODES, ids=lambda e: e.name)
def test_only_a_ros2_node_speaks_ros2(entry: NodeEntry, observed: dict[str, list[dict[str, Any]]]) -> None:
    foreign = [k for run in observed[entry.name] for keys in run["keys"].values() for k in keys
               if not k.startswith(KEYS.base + "/")]
    graph = [k for run in observed[entry.name] for k in run["tokens"] if k.startswith("@ros2_lv/")]
    if entry.ros2:
        assert foreign and graph, f"{entry.name} is marked ros2 but uses no ROS 2 key"
    else:
        assert not foreign and not graph, f"{entry.name} uses keys outside the project's base: {foreign + graph}"


def test_every_node_has_a_role_and_nothing_else_is_a_node() -> None:
    assert [n.name for n in NODES] == list(dict.fromkeys(n.name for n in NODES)), "a node name appears twice"
    assert {n.name for n in NODES} <= set(ROLES)
    assert set(ROLES) - {n.name for n in NODES} == {"router", "sensors", "monitor", "consumer", "operator", "launcher"}


def test_the_key_table_names_each_stream_of_the_registry() -> None:
    for s in STREAMS:
        for n in NODES:
            if s.name in n.subscribes or s.name in n.watches:
                assert n.name in s.subscribers.split(", ")
            if s.name in n.publishes or s.name in n.serves:
                assert n.name in s.publishers.split(", ")
    declared = {x for n in NODES for x in (*n.subscribes, *n.publishes, *n.serves, *n.watches)}
    assert declared <= {s.name for s in STREAMS}


def test_the_command_table_has_every_node_package() -> None:
    from perception.cli import COMMAND_PACKAGES

    for n in NODES:
        assert n.package in COMMAND_PACKAGES
        assert importlib.util.find_spec(f"{n.package}.commands") is not None, f"{n.package} has no commands module"


def test_the_stage_lists_are_the_registry_stages() -> None:
    from tools.demo.main import SERVICES
    from tools.demo.monitor import STAGES as MONITOR_STAGES
    from tools.doctor.core.facts import CHAIN
    from tools.doctor.core.facts import NODES as DOCTOR_NODES
    from tools.viewer.node import STAGES as VIEWER_STAGES

    assert SERVICES == DOCTOR_NODES == stages() == ("detector", "localizer", "embedder", "tracker")
    assert VIEWER_STAGES == ("camera", *stages())
    assert tuple(name for name, _, _ in MONITOR_STAGES) == stages()
    # the doctor's chain: each stream is made by the node that publishes it, from a stream that node reads
    for stream_name, producer, source in CHAIN:
        if producer:
            assert stream_name in node(producer).publishes and source in node(producer).subscribes


def test_the_import_rules_cover_every_node() -> None:
    ini = configparser.ConfigParser()
    ini.read(ROOT / ".importlinter")
    independent = ini["importlinter:contract:nodes-independent"]["modules"].split()
    assert sorted(independent) == sorted(n.package for n in NODES if n.package.startswith("services."))
    cores = ini["importlinter:contract:pure-cores"]["source_modules"].split()
    for n in NODES:
        if (ROOT / n.package.replace(".", "/") / "core").is_dir():
            assert f"{n.package}.core" in cores, f".importlinter's pure-cores contract misses {n.package}.core"


