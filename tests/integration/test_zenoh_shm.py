"""Zenoh's shared memory is kept for big messages (camera frames): a message of a few KB must
not make a process create and map a 16 MiB pool (the soak's mid-run RSS steps)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from common.transport.zenoh_config import SHM_THRESHOLD_BYTES, ZenohOptions, build_zenoh_config

PROBE = Path(__file__).resolve().parents[1] / "helpers" / "shm_probe.py"
KEY = "transport/shared_memory/transport_optimization/message_size_threshold"


def test_every_session_sends_only_big_messages_through_shared_memory(tmp_path: Path) -> None:
    assert json.loads(build_zenoh_config(ZenohOptions()).get_json(KEY)) == SHM_THRESHOLD_BYTES == 65536
    own = tmp_path / "zenoh.json5"
    own.write_text('{transport: {shared_memory: {transport_optimization: {message_size_threshold: 8192}}}}')
    assert json.loads(build_zenoh_config(ZenohOptions(config_file=own)).get_json(KEY)) == 8192  # a file's own value


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads RssShmem from /proc (Linux)")
def test_a_4kb_message_maps_no_shared_memory_pool_where_zenohs_default_maps_16_mib() -> None:
    added = {}
    for variant in ("ours", "zenoh-default"):
        out = subprocess.run([sys.executable, str(PROBE), variant], capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr[-2000:]
        added[variant] = json.loads(out.stdout.strip().splitlines()[-1])["shmem_kib_added"]
    assert added["zenoh-default"] >= 16 * 1024  # the control: a pool of 16 MiB, mapped
    assert added["ours"] < 1024
