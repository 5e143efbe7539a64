"""Sub-commands of the launcher package (names only, so ``perception --help`` stays fast)."""

COMMANDS = {
    "launch": ("tools.launcher.main", "start a router and services from a launch file and supervise them"),
    # The secure launch files (deploy/secure/) need these first; the module is in common/.
    "certs": ("common.certs_cli", "make the TLS certificates and the per-service credentials of deploy/secure/"),
}
