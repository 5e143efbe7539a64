COMMANDS = {
    "tracker": ("services.tracker.main", "run the multi-person tracker service (Zenoh)"),
    "track": ("services.tracker.track_cli", "run the tracker offline on a detections CSV file"),
    "forget": ("services.tracker.forget_cli", "make the running tracker forget a person (privacy), or everyone"),
}
