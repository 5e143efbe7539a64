"""The camera node's pure parts: image sources (OpenCV, RealSense), camera models and pacing."""
