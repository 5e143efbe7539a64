"""Typed publish/subscribe: the interface (``base``), its in-memory and Zenoh implementations,
Zenoh's configuration and security, and a router as a child process."""
