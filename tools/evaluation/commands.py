"""Sub-commands of the evaluation package (see perception/cli.py)."""

COMMANDS: dict[str, tuple[str, str]] = {
    "evaluate": ("tools.evaluation.evaluate_cli", "CLEAR MOT, IDF1, HOTA, recall errors and ID consistency of tracks against ground truth"),
}
