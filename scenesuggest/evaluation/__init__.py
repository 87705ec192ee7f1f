"""Offline evaluation: the engines ranked on held-out scenes, and the evaluation's tables."""
