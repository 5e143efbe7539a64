"""`perception doctor`: why there are detections but no tracks, in one command."""
