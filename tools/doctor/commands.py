"""Sub-commands of the doctor package (names only, so ``perception --help`` stays fast)."""

COMMANDS = {
    "doctor": ("tools.doctor.main", "check a running (or recorded) system and say why there are no tracks"),
}
