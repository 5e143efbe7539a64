"""The secure deployment (deploy/secure/) over real routers on loopback: TLS, passwords, access control.

Each test copies deploy/secure/ to a temporary folder, makes its certificates there with
``perception certs`` code, and starts ``perception router`` on a free port, multicast off.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from common.transport.certs import make_certs
from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import free_port, wait_for_port
from common.messages.schemas import Header, Tracks
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import TransportError, ZenohTransport, open_transport
from tests.helpers.scored_launch import ZenohClient, scored_run

pytestmark = [pytest.mark.zenoh]
PY = sys.executable
SECURE = Path(__file__).resolve().parents[2] / "deploy" / "secure"


@pytest.fixture(scope="module")
def secure_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """deploy/secure/ copied, with its certs/ made (and a second CA's, under other/)."""
    d = tmp_path_factory.mktemp("secure")
    for f in SECURE.iterdir():
        if f.is_file():
            shutil.copy(f, d / f.name)
    make_certs(d / "certs")
    make_certs(d / "other")
    return d


@pytest.fixture(scope="module")
def router(secure_dir: Path) -> Iterator[int]:
    """A secure router (TLS, mTLS, passwords, access control) on a free loopback port."""
    port = free_port()
    log = (secure_dir / f"router-{port}.log").open("wb")
    proc = subprocess.Popen([PY, "-m", "perception", "-q", "router", f"--listen=tls/127.0.0.1:{port}",
                             "--config", str(secure_dir / "router-single-pc.json5"), "--access-control"],
                            stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "RUST_LOG": "off"})
    assert wait_for_port("127.0.0.1", port, 20, proc), (secure_dir / f"router-{port}.log").read_text()
    yield port
    proc.send_signal(signal.SIGINT)
    proc.wait(10)


def _client(secure_dir: Path, port: int, role: str | None, config: str = "client.json5",
            credentials: Path | None = None) -> ZenohTransport:
    if credentials is None and role is not None:
        credentials = secure_dir / "certs" / "credentials" / f"{role}.txt"
    return open_transport(ZenohOptions(mode="client", connect=[f"tls/127.0.0.1:{port}"], config_file=secure_dir / config,
                                       credentials=credentials, connect_timeout_s=2.0))


def _tracks(seq: int) -> Tracks:
    return Tracks(header=Header(stamp_ns=time.time_ns(), seq=seq, source="test", frame_id="map"))


def test_the_services_credentials_open_a_session(secure_dir: Path, router: int) -> None:
    with _client(secure_dir, router, "tracker"):
        pass


def test_no_credentials_or_a_wrong_password_is_refused(secure_dir: Path, router: int, tmp_path: Path) -> None:
    with pytest.raises(TransportError, match="check the credentials"):
        _client(secure_dir, router, None)
    wrong = tmp_path / "wrong.txt"
    wrong.write_text("tracker:not-the-password\n")
    wrong.chmod(0o600)
    with pytest.raises(TransportError, match="refused the session"):
        _client(secure_dir, router, None, credentials=wrong)


def test_a_certificate_from_another_ca_is_refused(secure_dir: Path, router: int) -> None:
    conf = json.loads(json.dumps({"mode": "client", "transport": {"link": {"protocols": ["tls"], "tls": {
        "root_ca_certificate": "certs/ca.pem", "connect_certificate": "other/client.pem",
        "connect_private_key": "other/client.key", "enable_mtls": True}}}}))
    (secure_dir / "other-client.json5").write_text(json.dumps(conf))
    with pytest.raises(TransportError):  # the router does not trust the client's certificate
        _client(secure_dir, router, "tracker", config="other-client.json5")
    conf["transport"]["link"]["tls"].update(root_ca_certificate="other/ca.pem", connect_certificate="certs/client.pem",
                                            connect_private_key="certs/client.key")
    (secure_dir / "other-ca.json5").write_text(json.dumps(conf))
    with pytest.raises(TransportError):  # the client does not trust the router's certificate
        _client(secure_dir, router, "tracker", config="other-ca.json5")


def test_plain_tcp_is_refused(router: int) -> None:
    with pytest.raises(TransportError):
        open_transport(ZenohOptions(mode="client", connect=[f"tcp/127.0.0.1:{router}"], connect_timeout_s=2.0))


def test_the_embedders_credentials_cannot_publish_tracks(secure_dir: Path, router: int) -> None:
    keys = Keys(robot=f"acl{uuid.uuid4().hex[:6]}")
    with _client(secure_dir, router, "consumer") as nav, _client(secure_dir, router, "embedder") as emb, \
            _client(secure_dir, router, "tracker") as trk:
        sub = nav.subscribe(keys.tracks(), Tracks, RELIABLE)
        fake = emb.publisher(keys.tracks(), Tracks, RELIABLE)
        real = trk.publisher(keys.tracks(), Tracks, RELIABLE)
        assert real.wait_for_subscribers(5.0)
        # The router never tells the embedder that anyone reads tracks, and drops its puts.
        assert not fake.has_subscribers()
        fake.put(_tracks(1))  # sent to the router, which drops it
        real.put(_tracks(2))
        got = sub.recv(5.0)
        assert got is not None and got.msg.header.seq == 2
        assert sub.recv(1.0) is None  # and nothing from the embedder
        # The embedder may not even subscribe to tracks.
        peek = emb.subscribe(keys.tracks(), Tracks, RELIABLE)
        real.put(_tracks(3))
        assert sub.recv(5.0) is not None
        assert peek.recv(1.0) is None


def test_perception_status_with_credentials(secure_dir: Path, router: int) -> None:
    robot = f"st{uuid.uuid4().hex[:6]}"
    creds = secure_dir / "certs" / "credentials"
    common = ["--robot", robot, f"--connect=tls/127.0.0.1:{router}", "--config", str(secure_dir / "client.json5")]
    tracker = subprocess.Popen([PY, "-m", "perception", "-q", "tracker", "--no-memory", *common,
                                "--credentials", str(creds / "tracker.txt")], stderr=subprocess.PIPE, text=True)
    try:
        deadline, out = time.monotonic() + 60, ""
        while time.monotonic() < deadline and "tracker" not in out:
            done = subprocess.run([PY, "-m", "perception", "-q", "status", "--json", *common, "--credentials",
                                   str(creds / "monitor.txt")], capture_output=True, text=True, timeout=60, check=False)
            assert done.returncode == 0, done.stderr
            out = done.stdout
        rows = json.loads(out)
        assert [(r["service"], r["status"] is not None) for r in rows] == [("tracker", True)]
        # Without credentials, status stops with a message instead of an empty list.
        done = subprocess.run([PY, "-m", "perception", "-q", "status", *common, "--connect-timeout", "2"],
                              capture_output=True, text=True, timeout=60, check=False)
        assert done.returncode == 2 and "check the credentials" in done.stderr
    finally:
        tracker.send_signal(signal.SIGINT)
        tracker.wait(20)


def _launch(file: Path, log: Path, **env: str) -> subprocess.Popen[bytes]:
    # the tracker's ID memory goes next to the log, not to the user's state folder
    return subprocess.Popen([PY, "-m", "perception", "launch", str(file)], stdout=log.open("wb"), stderr=subprocess.STDOUT,
                            env={**os.environ, "RUST_LOG": "off", "XDG_STATE_HOME": str(log.parent), **env})


def _stop(proc: subprocess.Popen[bytes]) -> int:
    proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        return -9


#: Measured in 8 pairs of runs on the 2-core machine, with zero, one or two busy cores or other
#: jobs beside them: MOTA 0.767-0.782 on deploy/secure/, 0.776-0.782 on plain TCP (IDF1
#: 0.846-0.856 and 0.856-0.859), at most 1.5 points apart within a pair. They are separate
#: real-time runs: a frame skipped under load (latest-only) or a late embedding moves MOTA by
#: about half a point, so 5 points, three times the largest gap seen, is room for a few more
#: in one run than in the other. The floor is perception demo's (tests/integration/test_pipeline_integration.py).
SCORE_TOLERANCE = 0.05
MOTA_FLOOR = 0.55


@pytest.mark.slow
def test_the_pipeline_runs_end_to_end_on_deploy_secure_and_scores_as_on_plain_tcp(secure_dir: Path,
                                                                                    tmp_path: Path) -> None:
    """deploy/secure/single-pc.yaml and deploy/single-pc.yaml, each fed the same simulated scenario
    (still, seed 0, 20 s at 10 fps, 320x240) and scored against its ground truth: tracks reach
    navigation's consumer role, and MOTA and IDF1 agree."""
    secure_port, plain_port = free_port(), free_port()
    secure = scored_run(secure_dir / "single-pc.yaml", secure_port,
                        ZenohClient(f"tls/127.0.0.1:{secure_port}", secure_dir / "client.json5",
                                    str(secure_dir / "certs" / "credentials" / "{role}.txt")),
                        tmp_path / "secure", f"sec{uuid.uuid4().hex[:6]}")
    plain = scored_run(SECURE.parent / "single-pc.yaml", plain_port, ZenohClient(f"tcp/127.0.0.1:{plain_port}"),
                       tmp_path / "plain", f"pln{uuid.uuid4().hex[:6]}")
    assert (secure.launch_status, plain.launch_status) == (0, 0), secure.log + plain.log
    assert secure.consumer_tracks > 0, secure.log  # the consumer role reads tracks through the access control
    s, p = secure.overall, plain.overall
    summary = {k: (s[k], p[k]) for k in ("objects", "misses", "false_positives", "id_switches", "mota", "idf1")}
    assert s["objects"] == p["objects"] > 100, summary  # the same ground truth, all of it received
    assert min(s["mota"], p["mota"]) >= MOTA_FLOOR, summary
    assert abs(s["mota"] - p["mota"]) <= SCORE_TOLERANCE, summary
    assert abs(s["idf1"] - p["idf1"]) <= SCORE_TOLERANCE, summary


@pytest.mark.slow
def test_two_routers_over_tls(secure_dir: Path, tmp_path: Path) -> None:
    """The HRI and navigation PCs' routers on loopback: the link is TLS, a tracker on one reaches a consumer on the other."""
    robot, hri, nav = f"two{uuid.uuid4().hex[:6]}", free_port(), free_port()
    env = {"ROBOT": robot, "HRI_PC": "127.0.0.1", "NAV_PC": "127.0.0.1", "HRI_PORT": str(hri), "NAV_PORT": str(nav)}
    procs = [_launch(secure_dir / "hri-pc.yaml", tmp_path / "hri.log", **env),
             _launch(secure_dir / "nav-pc.yaml", tmp_path / "nav.log", **env)]
    try:
        assert wait_for_port("127.0.0.1", hri, 30) and wait_for_port("127.0.0.1", nav, 30)
        with _client(secure_dir, hri, "monitor") as mon:
            deadline, alive = time.monotonic() + 60, []
            while time.monotonic() < deadline and not {"tracker", "localizer"} <= {Keys(robot=robot).parse_alive(a).service for a in alive}:
                alive = mon.alive(Keys(robot=robot).alive(), timeout=1.0)
            services = {Keys(robot=robot).parse_alive(a).service for a in alive}
            # the navigation PC's services, seen through the HRI PC's router
            assert {"tracker", "localizer"} <= services, (tmp_path / "nav.log").read_text()[-2000:]
    finally:
        codes = [_stop(p) for p in procs]
    assert codes == [0, 0]
