"""Benchmarks: scripts that print figures (medians, ratios), measured side by side in one process."""
