"""The attention node: keeps a chosen person in view with the pan/tilt head (Ban et al.)."""
