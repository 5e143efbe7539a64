"""The simulator core: apartment, bodies, motion, robot, renderer and the per-frame ground truth (numpy and scipy, no I/O)."""
