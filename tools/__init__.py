"""Tools around the perception services: simulator, record/replay, evaluation, launcher, demo.

A service package (``services.*``) never imports from here.
"""
