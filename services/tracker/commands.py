COMMANDS = {
    "tracker": ("services.tracker.main", "run the multi-person tracker service (Zenoh)"),
    "track": ("services.tracker.track_cli", "run the tracker offline on a detections CSV file"),
}
