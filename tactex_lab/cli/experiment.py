"""``tactex experiment <name>``: each experiment module registers its own sub-command.

A module listed in ``MODULES`` defines ``register(subparsers)`` that adds one parser whose
``func(args) -> int`` runs the experiment.
"""

from __future__ import annotations

import argparse
import importlib

from tactex_ros.cli.options import builds

MODULES: list[str] = ["classify", "explore", "humans", "pareto", "stability", "saliency",
                      "real_sessions", "unseen", "real", "accuracy_charts", "stability_real",
                      "ladder", "fabric_library", "families", "sim_embedding", "evidence_sim", "stop_rules",
                      "embedding_search"]


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    e = sub.add_parser("experiment", help="experiments: results folder with JSON and figures")
    if not builds(command, "experiment"):
        return                        # the experiments import torch: only when asked for
    esub = e.add_subparsers(dest="ecmd", required=True)
    for name in MODULES:
        importlib.import_module(f"tactex_lab.experiments.{name}").register(esub)
