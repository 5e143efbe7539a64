"""Sub-commands of the evaluation package (see services/cli.py)."""

COMMANDS: dict[str, tuple[str, str]] = {
    "evaluate": ("services.evaluation.cli", "CLEAR MOT, IDF1, recall errors and ID consistency of tracks against ground truth"),
}
