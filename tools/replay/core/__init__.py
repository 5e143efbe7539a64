"""Replay logic without I/O: stamp ordering and pacing, RGB-D pairing, topic mapping."""
