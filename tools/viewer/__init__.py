"""``perception view``: the operator's live page (and the Foxglove bridge) over the Zenoh streams."""
