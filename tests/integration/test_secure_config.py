"""Certificates, credentials and access rules of the secure deployment, without a router."""

from __future__ import annotations

import json
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from common.transport.acl import access_control, grants
from common.transport.certs import ROLES, issue_certificate, make_certs
from common.messages.keys import Keys
from common.transport.zenoh_config import ZenohOptions, build_zenoh_config
from common.transport.zenoh_security import SecurityError

PY = sys.executable
SECURE = Path(__file__).resolve().parents[2] / "deploy" / "secure"


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("certs")
    make_certs(d, ["nav-pc", "192.168.1.20"])
    return d


def _secure_copy(tmp: Path, certs: Path | None) -> Path:
    d = tmp / "secure"
    d.mkdir()
    for f in SECURE.iterdir():
        if f.is_file():
            shutil.copy(f, d / f.name)
    if certs is not None:
        shutil.copytree(certs, d / "certs")
    return d


def test_certs_writes_keys_and_passwords_owner_only(certs: Path) -> None:
    secret = [certs / "ca.key", certs / "router.key", certs / "client.key", certs / "users.txt",
              *(certs / "credentials" / f"{r}.txt" for r in ROLES)]
    for f in secret:
        assert stat.S_IMODE(f.stat().st_mode) == 0o600, f
    users = dict(line.split(":", 1) for line in (certs / "users.txt").read_text().split())
    assert sorted(users) == sorted(ROLES)
    assert len(set(users.values())) == len(ROLES)  # a password of its own for every role
    text = subprocess.run(["openssl", "x509", "-noout", "-text", "-in", str(certs / "router.pem")],
                          capture_output=True, text=True, check=True).stdout
    for name in ("DNS:localhost", "IP Address:127.0.0.1", "DNS:nav-pc", "IP Address:192.168.1.20"):
        assert name in text
    subprocess.run(["openssl", "verify", "-CAfile", str(certs / "ca.pem"), str(certs / "router.pem"),
                    str(certs / "client.pem")], check=True, capture_output=True)


def test_certs_refuses_to_overwrite(certs: Path) -> None:
    done = subprocess.run([PY, "-m", "perception", "certs", str(certs)], capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "--force" in done.stderr


def test_relative_tls_paths_are_read_from_the_config_folder(tmp_path: Path, certs: Path) -> None:
    d = _secure_copy(tmp_path, certs)
    conf = build_zenoh_config(ZenohOptions(config_file=d / "client.json5", credentials=d / "certs/credentials/tracker.txt"))
    assert json.loads(conf.get_json("transport/link/tls/root_ca_certificate")) == str(d.resolve() / "certs" / "ca.pem")
    assert json.loads(conf.get_json("transport/auth/usrpwd/user")) == "tracker"


@pytest.mark.parametrize("case", ["missing", "folder", "not-pem", "expired"])
def test_a_bad_certificate_is_named(tmp_path: Path, certs: Path, case: str) -> None:
    d = _secure_copy(tmp_path, certs)
    ca = d / "certs" / "ca.pem"
    if case == "missing":
        ca.unlink()
    elif case == "folder":
        ca.unlink()
        ca.mkdir()
    elif case == "not-pem":
        ca.write_text("hello\n")
    else:
        issue_certificate(d / "certs", "client", "perception-client", (ca, d / "certs" / "ca.key"), days=-1)
    want = {"missing": "does not exist", "folder": "is a folder", "not-pem": "not a PEM certificate",
            "expired": "expired on"}[case]
    with pytest.raises(SecurityError, match=want) as err:
        build_zenoh_config(ZenohOptions(config_file=d / "client.json5"))
    assert str(ca if case != "expired" else d / "certs" / "client.pem") in str(err.value)


@pytest.mark.parametrize("which", ["credentials", "key"])
def test_a_secret_readable_by_others_is_refused(tmp_path: Path, certs: Path, which: str) -> None:
    d = _secure_copy(tmp_path, certs)
    path = d / "certs" / ("credentials/detector.txt" if which == "credentials" else "client.key")
    path.chmod(0o644)
    with pytest.raises(SecurityError, match=r"mode 0644.*chmod 600") as err:
        build_zenoh_config(ZenohOptions(config_file=d / "client.json5", credentials=d / "certs/credentials/detector.txt"))
    assert str(path) in str(err.value)


def test_commands_stop_at_start_up_naming_the_file(tmp_path: Path, certs: Path) -> None:
    d = _secure_copy(tmp_path, certs)
    creds = d / "certs" / "credentials" / "monitor.txt"
    creds.chmod(0o640)
    done = subprocess.run([PY, "-m", "perception", "status", "--config", str(d / "client.json5"), "--credentials",
                           str(creds)], capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2
    assert f"credentials file {creds} has mode 0640" in done.stderr


def test_launch_without_certificates_says_to_make_them(tmp_path: Path) -> None:
    d = _secure_copy(tmp_path, None)
    done = subprocess.run([PY, "-m", "perception", "launch", str(d / "single-pc.yaml")], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 2
    assert "certs/credentials/launcher.txt does not exist" in done.stderr and "perception certs" in done.stderr


def test_launch_with_an_expired_router_certificate_starts_nothing(tmp_path: Path, certs: Path) -> None:
    d = _secure_copy(tmp_path, certs)
    c = d / "certs"
    issue_certificate(c, "router", "router", (c / "ca.pem", c / "ca.key"), server=True, days=-1)
    done = subprocess.run([PY, "-m", "perception", "launch", str(d / "single-pc.yaml")], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 2
    assert f"certificate {c / 'router.pem'} expired on" in done.stderr
    assert "[router]" not in done.stdout


def test_the_secure_launch_files_are_valid(tmp_path: Path, certs: Path) -> None:
    d = _secure_copy(tmp_path, certs)
    for name in ("single-pc.yaml", "hri-pc.yaml", "nav-pc.yaml"):
        done = subprocess.run([PY, "-m", "perception", "launch", str(d / name), "--dry-run"], capture_output=True,
                              text=True, timeout=60, check=False)
        assert done.returncode == 0, done.stderr
        assert "--access-control" in done.stdout and "--listen=tls/" in done.stdout
        assert done.stdout.count("--credentials") >= 2


def test_least_privilege_rules() -> None:
    g = grants()
    k = Keys(robot="robot-name")
    assert set(g) == set(ROLES)
    publishers_of_tracks = [role for role, grant in g.items() if k.tracks() in grant.publish or grant.everything]
    assert publishers_of_tracks == ["router", "tracker"]
    assert set(g["detector"].publish) == {k.detections("*"), k.status("detector", "*")}
    assert set(g["embedder"].publish) == {k.embeddings("*"), k.status("embedder", "*")}
    assert g["monitor"].publish == () and g["consumer"].publish == ()
    acl = access_control()
    assert acl["enabled"] and acl["default_permission"] == "deny"
    rules = {r["id"]: r for r in acl["rules"]}
    everything = [r for r in acl["rules"] if "**" in r["key_exprs"]]
    assert [r["id"] for r in everything] == ["router-all"]
    for policy in acl["policies"]:
        assert all(rid in rules for rid in policy["rules"])
    assert all(k2.startswith("pp/*/perception/v1/") for r in acl["rules"] if not r["id"].startswith(("router-all", "ros2-"))
               for k2 in r["key_exprs"])
    # the ros2 node alone reaches outside the project's keys: ROS 2 domain 0 (ROS_DOMAIN_ID), its graph and history
    outside = {k2 for r in acl["rules"] if r["id"].startswith("ros2-") for k2 in r["key_exprs"]
               if not k2.startswith("pp/*/perception/v1/")}
    assert outside == {"0/**", "0/**/@adv/**", "@ros2_lv/0/**"}
