"""Names and sizes shared by the learning code and the nodes that do not learn, torch-free:
nodes, the graph description and the launch file import these without importing torch."""

from __future__ import annotations

FRAME_H, FRAME_W = 240, 320            # GelSight Mini frame [px]
MODEL_NAMES = ("small_inception", "inception_v3", "inception_v3_random")
STRATEGY_NAMES = ("variance", "entropy", "random", "yoto", "bald", "infogain")
