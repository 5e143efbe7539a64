"""The diagnosis without I/O: observed facts in, checklist out."""
