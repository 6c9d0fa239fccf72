"""Data: MJCF ↔ robot graph, the feature registry and datasets."""
