"""Observations: what the estimators see of an image (tracked feature points; later, silhouettes)."""
