"""Keys.parse_alive: the (service, instance) of a liveliness key, and nothing else."""

from __future__ import annotations

import pytest

from common.messages.keys import AliveKey, Keys

KEYS = Keys(robot="mbot")


@pytest.mark.parametrize(("service", "instance"), [("tracker", "x"), ("detector", "host-1234"), ("selfcheck", "a.b_c")])
def test_parse_alive_inverts_alive(service: str, instance: str) -> None:
    parsed = KEYS.parse_alive(KEYS.alive(service, instance))
    assert parsed == AliveKey(service, instance)
    assert (parsed.service, parsed.instance) == (service, instance)


def test_parse_alive_with_a_longer_prefix() -> None:
    keys = Keys(robot="r2", prefix="site/pp")
    assert keys.parse_alive("site/pp/r2/perception/v1/alive/embedder/7") == ("embedder", "7")


@pytest.mark.parametrize(
    "key",
    [
        "pp/mbot/perception/v1/alive/tracker",  # no instance
        "pp/mbot/perception/v1/alive/tracker/x/y",  # one chunk too many
        "pp/mbot/perception/v1/alive//x",  # empty service
        "pp/mbot/perception/v1/alive/tracker/",  # empty instance
        "pp/mbot/perception/v1/alive/*/*",  # the pattern, not a key
        "pp/mbot/perception/v1/status/tracker/x",  # another stream
        "pp/other/perception/v1/alive/tracker/x",  # another robot
        "pp/mbot/perception/v2/alive/tracker/x",  # another version
        "xx/pp/mbot/perception/v1/alive/tracker/x",  # something before the prefix
        "tracker/x",
        "",
    ],
)
def test_parse_alive_rejects_other_keys(key: str) -> None:
    with pytest.raises(ValueError, match="not a liveliness key"):
        KEYS.parse_alive(key)


def test_status_lists_each_live_token_as_service_and_instance() -> None:
    from common.transport.memory import MemoryBus, MemoryTransport
    from tools.system.status_cli import collect

    bus = MemoryBus()
    service, client = MemoryTransport(bus), MemoryTransport(bus)
    service.declare_token(KEYS.alive("tracker", "i1"))
    service.declare_token(KEYS.alive("detector", "i2"))
    assert sorted(collect(client, KEYS, timeout=0.1)) == [("detector", "i2", None), ("tracker", "i1", None)]
