"""Sub-commands of the system package (names only, so ``perception --help`` stays fast)."""

COMMANDS = {
    "router": ("tools.system.router_cli", "run a Zenoh router in this process"),
    "status": ("tools.system.status_cli", "list the live services with their host and counters"),
    "selfcheck": ("tools.system.selfcheck_cli", "start a router and exchange one message of every type through it"),
    "keys": ("tools.system.keys_cli", "print the key expressions of a robot and their delivery policy"),
    # The secure launch files (deploy/secure/) need these first.
    "certs": ("tools.system.certs_cli", "make the TLS certificates and the per-service credentials of deploy/secure/"),
}
