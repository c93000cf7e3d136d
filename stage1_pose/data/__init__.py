"""Paired music + dance data: the built-in synthetic generator, the dataset folder layout, training windows
and importers for OpenPose and AIST++ recordings."""
