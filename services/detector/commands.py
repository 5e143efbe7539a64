"""Sub-commands of the detector package (see perception/cli.py)."""

COMMANDS = {
    "detector": ("services.detector.main", "run the person detector service on a camera's frames"),
    "detect": ("services.detector.detect_cli", "detect people in image files, write one JSON line per image"),
}
