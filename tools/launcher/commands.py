"""Sub-commands of the launcher package (names only, so ``perception --help`` stays fast)."""

COMMANDS = {
    "launch": ("tools.launcher.main", "start a router and services from a launch file and supervise them"),
}
