"""Make the robot's TLS certificates and Zenoh credentials with the ``openssl`` command.

One folder holds everything secret that the secure deployment (``deploy/secure/``) reads:

=============================  ===========================================================
``ca.pem`` / ``ca.key``        the robot's own certificate authority (keep ``ca.key`` off
                               the robot once the certificates are made)
``router.pem`` / ``router.key`` both PCs' routers: TLS server, and client on the
                               router-to-router link; its names are the ``--hosts``
``client.pem`` / ``client.key`` the services' client certificate (mutual TLS)
``users.txt``                  the routers' user/password dictionary (``user:password``)
``credentials/ROLE.txt``       one ``user:password`` line per role (:data:`ROLES`)
=============================  ===========================================================

Private keys, the dictionary and the credentials are written with mode 0600.
"""

from __future__ import annotations

import ipaddress
import os
import secrets
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from common.transport.acl import ROLES_NOT_NODES, ROUTER_COMMON_NAME
from common.messages.registry import NODES

__all__ = ["CertsError", "DEFAULT_HOSTS", "ROLES", "make_certs", "issue_certificate", "make_ca"]

#: Who gets a user name and password: each service, the other router, the tools.
ROLES: tuple[str, ...] = tuple(dict.fromkeys(("router", *(n.name for n in NODES), *ROLES_NOT_NODES)))
#: Names the router certificate always holds, so that local clients can verify it.
DEFAULT_HOSTS: tuple[str, ...] = ("localhost", "127.0.0.1")
_CURVE = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
_SECRET = 0o600


class CertsError(RuntimeError):
    """A certificate could not be made; the message says what openssl said."""


def _openssl(*args: str) -> None:
    exe = shutil.which("openssl")
    if exe is None:
        raise CertsError("the openssl command is not installed (apt install openssl)")
    done = subprocess.run([exe, *args], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise CertsError(f"openssl {args[0]} failed: {done.stderr.strip()[-500:]}")


def _san(hosts: Sequence[str]) -> str:
    names = []
    for h in dict.fromkeys([*DEFAULT_HOSTS, *hosts]):
        try:
            ipaddress.ip_address(h)
            names.append(f"IP:{h}")
        except ValueError:
            names.append(f"DNS:{h}")
    return ",".join(names)


def make_ca(out: Path, days: int = 3650, name: str = "people-perception robot CA") -> tuple[Path, Path]:
    """A self-signed CA: (``out/ca.pem``, ``out/ca.key``)."""
    cert, key = out / "ca.pem", out / "ca.key"
    _openssl("req", "-x509", *_CURVE, "-keyout", str(key), "-out", str(cert), "-days", str(days),
             "-subj", f"/CN={name}", "-addext", "basicConstraints=critical,CA:TRUE",
             "-addext", "keyUsage=critical,keyCertSign,cRLSign")
    key.chmod(_SECRET)
    return cert, key


def issue_certificate(out: Path, stem: str, common_name: str, ca: tuple[Path, Path], *, hosts: Sequence[str] = (),
                      server: bool = False, days: int = 825) -> tuple[Path, Path]:
    """A certificate signed by ``ca`` (cert, key): ``out/STEM.pem`` and ``out/STEM.key``.

    ``server`` adds the TLS server usage and ``hosts`` (plus :data:`DEFAULT_HOSTS`) as its
    subject alternative names. A negative ``days`` makes an expired certificate (tests).
    """
    cert, key = out / f"{stem}.pem", out / f"{stem}.key"
    usage = "serverAuth,clientAuth" if server else "clientAuth"
    lines = ["basicConstraints=critical,CA:FALSE", "keyUsage=critical,digitalSignature,keyEncipherment",
             f"extendedKeyUsage={usage}"]
    if server:
        lines.append(f"subjectAltName={_san(hosts)}")
    with tempfile.TemporaryDirectory(prefix="perception-certs-") as tmp:
        csr, ext = Path(tmp) / "req.csr", Path(tmp) / "ext.cnf"
        ext.write_text("\n".join(lines) + "\n")
        _openssl("req", "-new", *_CURVE, "-keyout", str(key), "-out", str(csr), "-subj", f"/CN={common_name}")
        key.chmod(_SECRET)
        _openssl("x509", "-req", "-in", str(csr), "-CA", str(ca[0]), "-CAkey", str(ca[1]),
                 "-set_serial", str(secrets.randbits(63)), "-days", str(days), "-extfile", str(ext), "-out", str(cert))
    return cert, key


def _write_secret(path: Path, text: str) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, _SECRET)
    with os.fdopen(fd, "w") as f:
        f.write(text)
    path.chmod(_SECRET)


def make_certs(out: Path, hosts: Sequence[str] = (), *, days: int = 825, force: bool = False) -> list[Path]:
    """Write the CA, the router and client certificates and every role's credentials to ``out``.

    Refuses to overwrite an existing ``out/ca.pem`` unless ``force``: new certificates
    must then be installed on both PCs at once. Returns the files written.
    """
    if (out / "ca.pem").exists() and not force:
        raise CertsError(f"{out / 'ca.pem'} exists; pass --force to replace every certificate and password in {out}")
    out.mkdir(parents=True, exist_ok=True)
    (out / "credentials").mkdir(mode=0o700, exist_ok=True)
    ca = make_ca(out, days=max(days, 3650))
    files = [*ca]
    files += issue_certificate(out, "router", ROUTER_COMMON_NAME, ca, hosts=hosts, server=True, days=days)
    files += issue_certificate(out, "client", "perception-client", ca, days=days)
    passwords = {role: secrets.token_urlsafe(24) for role in ROLES}
    _write_secret(out / "users.txt", "".join(f"{r}:{p}\n" for r, p in passwords.items()))
    files.append(out / "users.txt")
    for role, password in passwords.items():
        path = out / "credentials" / f"{role}.txt"
        _write_secret(path, f"{role}:{password}\n")
        files.append(path)
    return files
