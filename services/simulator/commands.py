COMMANDS = {
    "simulate": ("services.simulator.main", "publish a simulated RGB-D camera, transforms and people ground truth"),
}
