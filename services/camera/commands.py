COMMANDS = {
    "camera": ("services.camera.main", "run the camera node: a camera, video file or folder of images to frames/{camera}"),
}
