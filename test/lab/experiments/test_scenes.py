"""Hard scenes (``tactex_lab/experiments/scenes.py``): the metric of another library, the
nearest classes and the scene drawn from them, on small fixed examples."""

import numpy as np
import pytest

from tactex_ros.core.errors import InputError
from tactex_lab.experiments.scenes import (VAR_FLOOR, hard_scene, metric_weights,
                                           nearest_classes)


def test_metric_weights_are_the_inverse_pooled_within_class_variance():
    w = metric_weights({"a": np.array([[0.0, 0.0], [2.0, 0.0]]),
                        "b": np.array([[0.0, 1.0], [0.0, 3.0]]),
                        "c": np.array([[5.0, 5.0]])})          # one press: adds nothing
    # SS = (2, 2) over 2 degrees of freedom: variance (1, 1), floor 1e-3 x median 1
    assert w.tolist() == pytest.approx([1 / (1 + VAR_FLOOR)] * 2, rel=1e-12)
    with pytest.raises(InputError, match="two presses"):
        metric_weights({"a": np.array([[1.0, 2.0]])})


MEANS = {"a": np.array([0.0, 0.0]), "b": np.array([1.0, 0.0]), "c": np.array([0.0, 2.0]),
         "d": np.array([3.0, 3.0])}


def test_nearest_classes_by_the_weighted_distance_ties_by_name():
    assert nearest_classes(MEANS, np.array([1.0, 1.0]), "a", 3) == ["b", "c", "d"]  # 1, 4, 18
    # weight 0.25 on the second dimension: b and c both at 1, d at 11.25
    assert nearest_classes(MEANS, np.array([1.0, 0.25]), "a", 2) == ["b", "c"]
    assert nearest_classes(MEANS, np.array([0.0, 1.0]), "d", 2) == ["c", "a"]  # 1, 9 (b: 9)
    with pytest.raises(InputError):
        nearest_classes(MEANS, np.ones(2), "a", 4)


def test_a_hard_scene_is_the_reference_and_its_nearest_classes():
    for seed in range(6):
        classes, truth = hard_scene(MEANS, np.array([1.0, 1.0]), 3, seed)
        ref, comps = classes[0], classes[1:]
        assert comps[truth - 1] == ref
        assert sorted(comps) == sorted([ref] + nearest_classes(MEANS, np.ones(2), ref, 2))
    assert hard_scene(MEANS, np.ones(2), 3, 0) == hard_scene(MEANS, np.ones(2), 3, 0)
    # seed 0 draws b (nearest: a at 1, c at 5); seed 1 draws d (c at 10, b at 13; a at 18)
    assert hard_scene(MEANS, np.ones(2), 3, 0) == (["b", "a", "b", "c"], 2)
    assert hard_scene(MEANS, np.ones(2), 3, 1) == (["d", "b", "d", "c"], 2)
    with pytest.raises(InputError, match="only 4"):
        hard_scene(MEANS, np.ones(2), 5, 0)
