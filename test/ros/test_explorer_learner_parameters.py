"""The explorer declares ``learner.model`` and then only the parameters of the learner it names
(the per-learner settings of ``core/config.py``), with the preset's values as defaults; the node
is made in this process with its own context (no spinning, nothing configured)."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from tactex_ros.core.paths import config_dir  # noqa: E402

pytestmark = pytest.mark.ros


def _declared(domain_id: int, params: dict) -> dict:
    from tactex_ros.ros.nodes.explorer_node import ExplorerNode
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    try:
        node = ExplorerNode(context=ctx, parameter_overrides=[
            Parameter(k, value=v) for k, v in {"autostart": False,
                                               "scene_file": str(config_dir() /
                                                                 "scene_sim.yaml"),
                                               **params}.items()])
        out = {n: node.get_parameter(n).value for n in node._parameters
               if n.startswith("learner.")}
        read_only = node.describe_parameter("learner.model").read_only
        node.destroy_node()
        return {"values": out, "model_read_only": read_only}
    finally:
        rclpy.shutdown(context=ctx)


def test_learner_parameters_follow_the_learner(domain_id) -> None:
    d = _declared(domain_id, {})
    assert d["model_read_only"]
    assert sorted(d["values"]) == sorted([
        "learner.model", "learner.guards", "learner.contact_flat_min", "learner.contact_min",
        "learner.contact_region_min", "learner.descriptor_frames", "learner.match_prior_scale",
        "learner.match_prior_strength", "learner.descriptor_no_contact",
        "learner.descriptor_height_map", "learner.descriptor_embedding",
        "learner.descriptor_embedding_frames", "learner.representation", "learner.representation_temperature",
        "learner.match_units", "learner.match_temperature", "learner.fabric_library"])
    s = _declared(domain_id, {"config": "seed_faithful"})["values"]
    assert (s["learner.model"], s["learner.input_size"], s["learner.epochs"],
            s["learner.bn_recalibrate"]) == ("small_inception", 299, 10, 0)
    assert "learner.match_temperature" not in s and "learner.auto_ladder" not in s
    a = _declared(domain_id, {"config": "cnn", "learner.model": "cnn_auto"})["values"]
    assert (a["learner.model"], a["learner.input_size"], a["learner.steps"],
            a["learner.auto_ladder"]) == ("cnn_auto", 48, 8,
                                          "small_inception@48,small_inception@96")
    lad = _declared(domain_id, {"learner.model": "auto"})["values"]
    assert (lad["learner.model"], lad["learner.ladder"], lad["learner.match_temperature"]) == \
        ("auto", "descriptor,representation,cnn", 0.0251)
    assert "learner.lr" not in lad and "learner.auto_ladder" not in lad
