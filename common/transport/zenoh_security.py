"""Check and complete the security part of a Zenoh config before a session opens.

Zenoh itself does the TLS, the user/password authentication and the access control; this
module only makes their files usable and their problems readable:

- relative file paths under ``transport/link/tls`` and the ``usrpwd`` dictionary are
  resolved against the folder of the config file that names them, so ``deploy/secure/``
  finds its ``certs/`` wherever it is installed;
- every certificate must exist, be readable, be a PEM certificate and be valid now;
- private keys, the router's password dictionary and a credentials file must be readable
  by their owner only (mode 0600 or stricter);
- a credentials file (``--credentials``, one ``user:password`` line) fills
  ``transport/auth/usrpwd/user`` and ``password``.

Each problem raises :class:`SecurityError` naming the file, before anything connects.
"""

from __future__ import annotations

import json
import shutil
import ssl
import stat
import subprocess
import time
from pathlib import Path
from typing import Any

__all__ = ["SecurityError", "check_certificate", "check_secret_file", "read_credentials", "secure_config",
           "security_files"]

_TLS = "transport/link/tls"
_CERTS = ("root_ca_certificate", "listen_certificate", "connect_certificate")
_KEYS = ("listen_private_key", "connect_private_key")
_DICTIONARY = "transport/auth/usrpwd/dictionary_file"


class SecurityError(ValueError):
    """A certificate, key or credentials file that cannot be used; the message names it."""


def _readable(path: Path, what: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise SecurityError(f"{what} {path} does not exist (make the certificates with `perception certs DIR`)") from None
    except IsADirectoryError:
        raise SecurityError(f"{what} {path} is a folder, not a file") from None
    except OSError as exc:
        raise SecurityError(f"{what} {path} cannot be read: {exc.strerror}") from None


def check_secret_file(path: Path, what: str) -> bytes:
    """The bytes of a file that only its owner may read; raises naming ``path`` otherwise."""
    data = _readable(path, what)
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & 0o077:
        raise SecurityError(f"{what} {path} has mode {mode:04o}: others can read it; "
                            f"it must be readable by its owner only (chmod 600 {path})")
    return data


def _not_after(path: Path) -> float | None:
    """The certificate's expiry time (epoch seconds), from ``openssl``; None without openssl."""
    exe = shutil.which("openssl")
    if exe is None:
        return None
    done = subprocess.run([exe, "x509", "-noout", "-enddate", "-in", str(path)], capture_output=True, text=True, check=False)
    if done.returncode != 0 or not done.stdout.startswith("notAfter="):
        raise SecurityError(f"certificate {path} is not a PEM certificate: {done.stderr.strip()[:200]}")
    return float(ssl.cert_time_to_seconds(done.stdout.strip().removeprefix("notAfter=")))


def check_certificate(path: Path, now: float | None = None) -> None:
    """Raise :class:`SecurityError` if ``path`` is missing, unreadable, not a certificate or expired."""
    data = _readable(path, "certificate")
    if b"-----BEGIN CERTIFICATE-----" not in data:
        raise SecurityError(f"certificate {path} is not a PEM certificate (no BEGIN CERTIFICATE line)")
    not_after = _not_after(path)
    if not_after is not None and not_after <= (time.time() if now is None else now):
        when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(not_after))
        raise SecurityError(f"certificate {path} expired on {when}; make new ones with `perception certs DIR --force` "
                            "and install them on both PCs")


def read_credentials(path: Path) -> tuple[str, str]:
    """(user, password) from a ``user:password`` file of mode 0600."""
    text = check_secret_file(path, "credentials file").decode("utf-8", errors="replace").strip()
    user, sep, password = text.partition(":")
    if not sep or not user or not password or "\n" in text:
        raise SecurityError(f"credentials file {path} must hold one line USER:PASSWORD")
    return user, password


def _get(conf: Any, key: str) -> Any:
    import zenoh

    try:
        return json.loads(conf.get_json(key))
    except zenoh.ZError:
        return None


def security_files(conf: Any, base: Path | None) -> list[tuple[str, Path]]:
    """(config key, resolved path) of every security file ``conf`` names."""
    out = []
    for name in (*_CERTS, *_KEYS):
        value = _get(conf, f"{_TLS}/{name}")
        if isinstance(value, str) and value:
            out.append((f"{_TLS}/{name}", _resolve(value, base)))
    value = _get(conf, _DICTIONARY)
    if isinstance(value, str) and value:
        out.append((_DICTIONARY, _resolve(value, base)))
    return out


def _resolve(value: str, base: Path | None) -> Path:
    p = Path(value).expanduser()
    return p if p.is_absolute() or base is None else base / p


def secure_config(conf: Any, config_file: Path | None, credentials: Path | None) -> None:
    """Check the security files ``conf`` names and make their paths absolute; apply ``credentials``."""
    base = config_file.resolve().parent if config_file is not None else None
    for key, path in security_files(conf, base):
        name = key.rsplit("/", 1)[1]
        if name in _CERTS:
            check_certificate(path)
        elif name in _KEYS:
            check_secret_file(path, "private key")
        else:
            check_secret_file(path, "password dictionary")
        conf.insert_json5(key, json.dumps(str(path)))
    if credentials is not None:
        user, password = read_credentials(credentials)
        conf.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
