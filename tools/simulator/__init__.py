"""A simulated robot: RGB-D camera driver, localization and people ground truth (``perception simulate``)."""
