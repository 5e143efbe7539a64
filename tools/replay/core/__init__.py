"""Replay logic without I/O: stamp ordering and pacing, topic mapping (RGB-D pairing: common/runtime/pairing.py)."""
