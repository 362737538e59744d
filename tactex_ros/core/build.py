"""The learner a trial's settings name, built.

The product's own learners are built in code: ``descriptor`` (``core/descriptor.py``,
``DescriptorSettings``) and ``auto``, the ladder (``core/ladder.py``, ``LadderSettings``, its
rungs built by this function too). Every other ``learner.model`` (the thesis CNNs and
``cnn_auto``: ``CnnSettings``, ``AutoSettings``) is a plug-in of group ``tactex.learners``
(``core/plugins.py``), imported only when a trial asks for it; so the product works from a
checkout that is not installed, and loads torch only for a configuration that names a CNN.
"""

from __future__ import annotations

from .config import LearnerSettings
from .descriptor import DescriptorLearner
from .ladder import Ladder
from .learners import Learner
from .plugins import LEARNERS, load


def make_learner(num_classes: int, cfg: LearnerSettings, seed: int = 0) -> Learner:
    """The learner ``cfg.model`` names over ``num_classes`` comparisons: ``descriptor`` and
    ``auto`` built here, any other a ``tactex.learners`` plug-in (InputError when it is not
    installed)."""
    if cfg.model == "descriptor":
        return DescriptorLearner(num_classes, cfg, seed=seed)
    if cfg.model == "auto":
        return Ladder(num_classes, cfg, seed, make=make_learner)
    return load(LEARNERS, cfg.model)(num_classes, cfg, seed)
