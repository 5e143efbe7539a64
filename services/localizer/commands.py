"""Sub-commands of the localizer package."""

COMMANDS = {
    "localizer": (
        "services.localizer.main",
        "run the localizer service: boxes + depth + transforms -> people in the map",
    ),
    "localize": (
        "services.localizer.localize_cli",
        "localize the boxes of a detections JSONL file on a depth image, print JSON",
    ),
    "calibrate-localizer": (
        "services.localizer.calibrate_cli",
        "a detector's foot-point noise against ground-truth boxes: the floor paths' settings",
    ),
}
