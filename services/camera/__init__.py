"""The camera node: a camera, a video file or a folder of images to frames/{camera}."""
