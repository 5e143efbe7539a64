"""The system's small commands: ``perception router``, ``status``, ``selfcheck``, ``keys`` and ``certs``."""
