"""Sub-commands of the viewer package (names only, so ``perception --help`` stays fast)."""

COMMANDS = {
    "view": ("tools.viewer.main", "serve a live page of the tracks, the camera and the nodes' health to a browser"),
}
