"""Offline CLEAR MOT / identity evaluation of tracker output (``perception evaluate``)."""
