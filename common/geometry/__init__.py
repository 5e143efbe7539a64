"""Geometry: the camera model, rigid transforms and the transform buffer, 4x4 poses, and their messages."""
