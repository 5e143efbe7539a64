"""Sub-commands of the laser package."""

COMMANDS = {
    "laser": (
        "services.laser.main",
        "run the laser node: scans/{laser} -> the people around the robot, in the map",
    ),
    "legs": (
        "services.laser.legs_cli",
        "the legs and people in a bag's or recording's laser scans, one JSON line a scan",
    ),
    "train-legs": (
        "services.laser.train_legs_cli",
        "train the leg classifier on the labelled dev scans (rebuilds the shipped model)",
    ),
}
