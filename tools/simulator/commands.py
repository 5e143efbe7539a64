COMMANDS = {
    "simulate": ("tools.simulator.main", "publish a simulated RGB-D camera, transforms and people ground truth"),
}
