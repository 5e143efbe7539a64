"""The messages: their schemas and wire codec, the keys they travel on, and the node registry behind the keys."""
