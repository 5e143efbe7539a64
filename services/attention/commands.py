COMMANDS = {
    "attention": ("services.attention.main", "run the attention node: keep a chosen person in view with the pan/tilt head"),
    "look": ("services.attention.look_cli", "tell the running attention node whom to look at (an ID, nearest, none)"),
}
