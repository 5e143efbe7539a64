"""Least-privilege Zenoh access control for the secure deployment, derived from :mod:`common.messages.keys`.

Each role (a user name of Zenoh's user/password authentication, see
:data:`common.transport.certs.ROLES`: one per node of :data:`common.messages.registry.NODES`, and the parties that
are not nodes) may publish, subscribe, serve, ask and declare liveliness on
its own keys only; the routers deny everything else (``default_permission: deny``). The
routers' ``access_control`` sections in ``deploy/secure/`` are this module's output
(``perception certs --print-acl``), and a test keeps them equal.

What each grant allows, as Zenoh's ACL messages and flows seen from the router:

- publish: ``put`` in; subscriber declarations out (so the publisher knows it has readers);
- subscribe: ``declare_subscriber`` in; ``put`` out;
- serve: ``declare_queryable`` and ``reply`` in; ``query`` out (also on ``answers``);
- ask: ``query`` in; ``reply`` and queryable declarations out;
- token: ``liveliness_token`` in;
- watch: ``declare_liveliness_subscriber`` and ``liveliness_query`` in; ``liveliness_token`` and ``reply`` out.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from common.messages.keys import DEFAULT_PREFIX, Keys
from common.messages.registry import NODES, NodeEntry, node

__all__ = ["Grant", "access_control", "grants"]

#: The common name of the routers' certificate (:func:`common.transport.certs.make_certs`).
ROUTER_COMMON_NAME = "router"
_ROBOT = "robot-name"  # stands for any robot, replaced by '*' in the rules
#: The roles that are not one node's own: the routers, the sensors, the tools and the people.
ROLES_NOT_NODES: tuple[str, ...] = ("router", "sensors", "monitor", "consumer", "operator", "launcher")


@dataclass(frozen=True)
class Grant:
    """The keys one role may use, as key expressions (wildcards allowed)."""

    publish: tuple[str, ...] = ()
    subscribe: tuple[str, ...] = ()
    serve: tuple[str, ...] = ()
    ask: tuple[str, ...] = ()
    token: tuple[str, ...] = ()
    watch: tuple[str, ...] = ()
    #: Where queries reach it beyond ``serve`` (``perception status`` asks ``status/*/*``,
    #: which the ACL does not count as inside ``status/detector/*``).
    answers: tuple[str, ...] = ()
    #: The other router: every message on every key.
    everything: bool = False


def ros2_domain() -> int:
    """The ROS 2 domain the ros2 node is granted: ``$ROS_DOMAIN_ID``, else 0."""
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    return int(text) if text.isdigit() else 0


def _node_grant(k: Keys, entry: NodeEntry, domain: int) -> Grant:
    """A node run by :func:`common.runtime.node.run_node`: its streams as :data:`common.messages.registry.NODES`
    declares them, plus its own status and liveliness. A node that speaks ROS 2 also gets ROS 2
    domain ``domain``: every topic (``<domain>/**``), the history of transient-local publishers
    (zenoh-ext's ``@adv`` keys, which no wildcard matches) and the graph (``@ros2_lv/<domain>/**``)."""
    status = k.status(entry.name, "*")

    def patterns(streams: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(k.pattern(s) for s in streams)

    ros: tuple[str, ...] = ()
    graph: tuple[str, ...] = ()
    if entry.ros2:
        ros = (f"{domain}/**", f"{domain}/**/@adv/**")
        graph = (f"@ros2_lv/{domain}/**", f"{domain}/**/@adv/**")
    return Grant(publish=(*patterns(entry.publishes), status, *ros), subscribe=(*patterns(entry.subscribes), *ros),
                 serve=(*patterns(entry.serves), status), ask=ros[1:], token=(k.alive(entry.name, "*"), *graph),
                 watch=(*patterns(entry.watches), *graph), answers=(k.status(),))


def grants(prefix: str = DEFAULT_PREFIX, domain: int | None = None) -> dict[str, Grant]:
    """Role -> grant, with keys of any robot under ``prefix``.

    Every node of :data:`common.messages.registry.NODES` logs in under its own name and is granted
    exactly the streams its entry declares.
    """
    k = Keys(robot=_ROBOT, prefix=prefix)
    sensors = ("simulator", "replay")
    # The tracker's queryables, as the registry lists them (query/track, ...).
    tracker_queries = tuple(k.pattern(s) for s in node("tracker").serves)
    out = {
        "router": Grant(everything=True),
        **{entry.name: _node_grant(k, entry, ros2_domain() if domain is None else domain) for entry in NODES},
        # The camera driver, the simulator or a replay: the robot's sensor streams (the
        # simulator reads detections to pace itself) and their own status.
        "sensors": Grant(publish=(k.frames("*"), k.tf(), k.tf_static(), k.groundtruth(), *(k.status(s, "*") for s in sensors)),
                         subscribe=(k.detections("*"),), serve=tuple(k.status(s, "*") for s in sensors),
                         token=tuple(k.alive(s, "*") for s in sensors), answers=(k.status(),)),
        # perception status / doctor / viewer / record: reads everything, writes nothing.
        "monitor": Grant(subscribe=(k.all(),), ask=(k.status(), k.track_query()), watch=(k.alive(),)),
        # A person at the robot: every query the tracker serves (track look-ups, and requests that change its memory).
        "operator": Grant(ask=tracker_queries, watch=(k.alive(),)),
        # Navigation and HRI: the tracks and the track query.
        "consumer": Grant(subscribe=(k.tracks(),), ask=(k.track_query(),), watch=(k.alive(),)),
        # perception launch reports services that stopped for good under their own status key.
        "launcher": Grant(publish=(k.status(),), serve=(k.status(),)),
    }
    return out


def _any_robot(key: str, prefix: str) -> str:
    return key.replace(f"{prefix}/{_ROBOT}/", f"{prefix}/*/", 1)


def _rules(role: str, g: Grant, prefix: str) -> list[dict[str, Any]]:
    if g.everything:
        every = ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable", "liveliness_token",
                 "liveliness_query", "declare_liveliness_subscriber"]
        return [{"id": f"{role}-all", "messages": every, "flows": ["ingress", "egress"], "permission": "allow",
                 "key_exprs": ["**"]}]
    table = (
        ("publish", g.publish, ["put"], ["declare_subscriber"]),
        ("subscribe", g.subscribe, ["declare_subscriber"], ["put"]),
        ("serve", g.serve, ["declare_queryable", "reply"], []),
        ("answer", (*g.serve, *g.answers), [], ["query"]),
        ("ask", g.ask, ["query"], ["reply", "declare_queryable"]),
        ("token", g.token, ["liveliness_token"], []),
        ("watch", g.watch, ["declare_liveliness_subscriber", "liveliness_query"], ["liveliness_token", "reply"]),
    )
    rules = []
    for what, keys, ingress, egress in table:
        exprs = [_any_robot(key, prefix) for key in keys]
        for flow, messages in (("ingress", ingress), ("egress", egress)):
            if exprs and messages:
                rules.append({"id": f"{role}-{what}-{flow}", "messages": messages, "flows": [flow],
                              "permission": "allow", "key_exprs": exprs})
    return rules


def access_control(prefix: str = DEFAULT_PREFIX) -> dict[str, Any]:
    """The routers' ``access_control`` section: every role's rules, everything else denied."""
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for role, g in grants(prefix).items():
        mine = _rules(role, g, prefix)
        rules += mine
        subjects.append({"id": role, "usernames": [role]})
        ids = [role]
        if g.everything:
            # The router that opened the link logs in with its password; the one that accepted it
            # is known to the other side only by its TLS certificate (common name "router").
            subjects.append({"id": f"{role}-certificate", "cert_common_names": [ROUTER_COMMON_NAME]})
            ids.append(f"{role}-certificate")
        policies.append({"id": role, "rules": [r["id"] for r in mine], "subjects": ids})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}
