"""What the viewer draws, computed from numpy arrays and plain values: no transport, no messages."""
