"""The learner a trial's settings name, built.

The product's own learners are built in code: ``descriptor`` (``core/descriptor.py``,
``DescriptorSettings``) and the ladders ``auto`` and ``cnn_auto`` (``core/ladder.py``,
``LadderSettings`` and ``AutoSettings``: ``is_ladder``; their rungs built by this function
too). Every other ``learner.model`` (the thesis CNNs, ``CnnSettings``: ``plugin``) is a
plug-in of group ``tactex.learners`` (``core/plugins.py``), imported only when a trial asks
for it; so the product works from a checkout that is not installed, and loads torch only for a
configuration that names a CNN.
"""

from __future__ import annotations

from .config import LearnerSettings
from .descriptor import DescriptorLearner
from .ladder import Ladder
from .learners import Learner
from .plugins import LEARNERS, load


def make_learner(num_classes: int, cfg: LearnerSettings, seed: int = 0) -> Learner:
    """The learner ``cfg.model`` names over ``num_classes`` comparisons: a ladder or the
    descriptor built here, a plug-in's (``cfg.plugin``) loaded from group ``tactex.learners``
    (InputError when it is not installed)."""
    if cfg.is_ladder:
        return Ladder(num_classes, cfg, seed, make=make_learner)
    if cfg.plugin:
        return load(LEARNERS, cfg.model)(num_classes, cfg, seed)
    return DescriptorLearner(num_classes, cfg, seed=seed)
