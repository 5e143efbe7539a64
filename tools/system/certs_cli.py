"""``perception certs DIR``: the CA, certificates and credentials of the secure deployment."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from common.transport.acl import access_control
from common.transport.certs import DEFAULT_HOSTS, ROLES, CertsError, make_certs
from common.runtime.cli_util import CliError

HELP = "make the TLS certificates and the per-service credentials of deploy/secure/"
DESCRIPTION = f"""\
Make, in DIR: a certificate authority (ca.pem, ca.key), the routers' certificate
(router.pem, router.key) valid for the --hosts names and addresses (always also
{', '.join(DEFAULT_HOSTS)}), the services' client certificate (client.pem, client.key),
the routers' password dictionary (users.txt) and one USER:PASSWORD file per role in
DIR/credentials/ ({', '.join(ROLES)}). Keys, passwords and the dictionary are written
with mode 0600. Uses the openssl command.

The secure launch files read DIR = deploy/secure/certs next to them:
  perception certs deploy/secure/certs
  perception certs /etc/people-perception/certs --hosts hri-pc nav-pc 192.168.1.10 192.168.1.20
Copy the folder to both PCs (the same files), owned by the user the services run as.

--acl prints the routers' access_control section instead (derived from the keys)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dir", type=Path, nargs="?", metavar="DIR", help="folder to write (created if missing)")
    parser.add_argument("--hosts", nargs="+", default=[], metavar="NAME_OR_ADDRESS",
                        help="names and IP addresses the routers are reached at (both PCs')")
    parser.add_argument("--days", type=int, default=825, help="validity of the router and client certificates (default 825)")
    parser.add_argument("--force", action="store_true", help="replace the certificates and passwords already in DIR")
    parser.add_argument("--acl", action="store_true", help="print the routers' access_control section (JSON) and exit")


def main(args: argparse.Namespace) -> int:
    if args.acl:
        print(json.dumps(access_control(), indent=2))
        return 0
    if args.dir is None:
        raise CliError("give the folder to write, e.g. perception certs deploy/secure/certs")
    if args.days < 1:
        raise CliError(f"--days must be at least 1 (got {args.days})")
    try:
        files = make_certs(args.dir, args.hosts, days=args.days, force=args.force)
    except (CertsError, OSError) as exc:
        raise CliError(str(exc)) from exc
    print(f"wrote {len(files)} files to {args.dir}: CA, router and client certificates "
          f"(router names: {', '.join(dict.fromkeys([*DEFAULT_HOSTS, *args.hosts]))}), credentials of "
          f"{', '.join(ROLES)}")
    print(f"keep {args.dir / 'ca.key'} off the robot once the certificates are made")
    return 0
