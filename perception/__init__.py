"""The ``perception`` command (``perception.cli``); ``python -m perception`` runs it too."""
