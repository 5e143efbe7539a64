"""The laser's pure cores: a 2-D scan's beams, its segments, their geometry, the leg classifier
and the people it pairs. numpy and scipy only; nothing here reads a file at import."""
