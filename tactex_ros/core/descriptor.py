"""The descriptor learner: texture descriptors of every touch and the Gaussian match belief.

The engine's cheapest model (``DescriptorSettings``, ``learner.model = 'descriptor'``): nothing
is trained; each touch becomes a rotation-invariant descriptor (``core/texture.py``) once,
when it is added, and a decision recomputes the belief over which comparison matches (``core/match.py``) in closed form.
It is a ``core.learners.Learner`` (``add_touch``, ``add_reference``, ``heldout_proba``,
``reference_probs``, ``belief``; no ``train_round``: nothing is trained) plus ``info_gain`` for
the ``infogain`` strategy and ``stop_chance`` for ``lookahead``.
"""

from __future__ import annotations

import numpy as np

from .config import DescriptorSettings
from .embedding import Embedding, embed_touch
from .embedding import load as load_embedding
from .embedding import resolve as resolve_embedding
from .errors import InputError
from .library import EVIDENCE_WEIGHT, FabricLibrary, LibraryBelief, library_belief
from .match import MatchModel
from .representation import Representation, load
from .texture import describe_touch, descriptor_dim
from .touch import Touch

#: Posterior draws of the belief returned by ``reference_probs`` (the (T, C) table).
DRAWS = 32


_REPRESENTATIONS: dict[str, Representation] = {}


def _load_representation(path: str) -> Representation:
    """A representation file, loaded once per process."""
    if path not in _REPRESENTATIONS:
        _REPRESENTATIONS[path] = load(path)
    return _REPRESENTATIONS[path]


def embedding_of(cfg: DescriptorSettings) -> Embedding | None:
    """The learned embedding ``learner.descriptor_embedding`` names (None: none), loaded once
    per process; InputError naming the setting when its file is missing or not one."""
    if not cfg.descriptor_embedding:
        return None
    try:
        return load_embedding(resolve_embedding(cfg.descriptor_embedding))
    except InputError as exc:
        raise InputError(f"learner.descriptor_embedding={cfg.descriptor_embedding}: {exc}") \
            from None


def descriptor_size(cfg: DescriptorSettings) -> int:
    """D, the size of the descriptors ``cfg`` makes: ``texture.descriptor_dim`` plus the
    embedding's size."""
    emb = embedding_of(cfg)
    return descriptor_dim(cfg.descriptor_height_map) + (emb.dim if emb is not None else 0)


def raw_descriptor(touch: Touch, cfg: DescriptorSettings) -> np.ndarray:
    """(D,) the texture descriptor of ``touch`` as ``cfg`` describes it (``descriptor_frames``,
    ``descriptor_no_contact``, ``descriptor_height_map``, ``descriptor_embedding``,
    ``descriptor_embedding_frames``: D =
    ``descriptor_size``), before any representation; the touch's own when it has one."""
    if touch.descriptor is not None:
        return np.asarray(touch.descriptor, dtype=np.float64)
    if not cfg.descriptor_no_contact:
        touch = Touch(touch.frame, None, touch.extra)
    x = describe_touch(touch, cfg.descriptor_frames, cfg.descriptor_height_map)
    emb = embedding_of(cfg)
    if emb is None:
        return x
    return np.concatenate([x, embed_touch(touch, cfg.descriptor_embedding_frames, emb)])


class DescriptorLearner:
    """Descriptors + match belief for one trial over ``num_classes`` comparison platforms."""

    model_name = "descriptor"

    def __init__(self, num_classes: int, cfg: DescriptorSettings, seed: int = 0) -> None:
        self.cfg = cfg
        self.num_classes = num_classes
        emb = embedding_of(cfg)          # a missing or foreign weights file: refused here
        rep = _load_representation(cfg.representation) if cfg.representation else None
        if rep is not None:
            rep.check_descriptor(cfg.descriptor_height_map, f"file {cfg.representation}",
                                 cfg.descriptor_frames, emb.identity if emb else "",
                                 emb.dim if emb else 0, cfg.descriptor_embedding_frames)
        self.match = MatchModel(num_classes, cfg.match_prior_scale, cfg.match_prior_strength,
                                cfg.match_temperature, scene_units=cfg.match_units == "scene")
        self.representation: Representation | None = None
        self.use_representation(rep)
        self._rng = np.random.default_rng([int(seed), 31])
        self._heldout: np.ndarray | None = None
        self.library: LibraryBelief | None = None
        self.library_state: dict = {"used": False}

    def use_representation(self, rep: Representation | None,
                           temperature: float | None = None) -> None:
        """Before the first touch: describe touches through ``rep`` (a prepared representation
        held in memory, e.g. one a class fold fitted; None: the raw descriptor) in place of the
        settings' file, with the belief temperature ``temperature`` when given, else the
        representation's calibrated one where the settings use it
        (``representation_temperature``) and it has one, else ``match_temperature``."""
        if self.match.counts.any():
            raise InputError("use_representation: the learner has touches already")
        if temperature is None:
            temperature = (rep.temperature if rep is not None
                           and self.cfg.representation_temperature
                           and np.isfinite(rep.temperature) else self.cfg.match_temperature)
        if not (np.isfinite(temperature) and temperature > 0):
            raise InputError(f"belief temperature must be > 0 and finite, got {temperature}")
        self.representation = rep
        self.match.beta = float(temperature)

    def use_library(self, lib: FabricLibrary | None, weight: float = EVIDENCE_WEIGHT) -> None:
        """Let the belief ask the fabric library ``lib`` too (``core/library.py``; None: the
        scene-only belief; ``weight``: of its evidence); ``library_state`` says what the trial
        saw."""
        if lib is None:
            self.library, self.library_state = None, {"used": False}
            return
        want = descriptor_size(self.cfg)
        if lib.presses and lib.descriptors.shape[1] != want:
            raise InputError(
                f"fabric library: its descriptors have size {lib.descriptors.shape[1]}, this "
                f"learner's {want} (learner.descriptor_height_map="
                f"{str(self.cfg.descriptor_height_map).lower()}, learner.descriptor_embedding="
                f"{self.cfg.descriptor_embedding!r}): set learner.descriptor_height_map="
                f"{str(not self.cfg.descriptor_height_map).lower()} or the embedding it was "
                "filed with, or learner.fabric_library=false for this record folder")
        apply = self.representation.apply if self.representation is not None else None
        self.library = library_belief(lib, apply, self.match.beta, weight)
        self.library_state = {"used": True, **lib.state()}

    def _describe(self, touch: Touch) -> np.ndarray:
        x = raw_descriptor(touch, self.cfg)
        return x if self.representation is None else self.representation.apply(x)

    def add_touch(self, touch: Touch, label: int) -> np.ndarray:
        """Store the descriptor of a comparison touch under ``label`` (0..C-1); returns it."""
        if not 0 <= label < self.num_classes:
            raise InputError(f"label {label} outside 0..{self.num_classes - 1}")
        x = self._describe(touch)
        self._heldout = self.match.comparison_proba(x) if self.match.ready else None
        self.match.add(label + 1, x)
        return x

    def add_reference(self, touch: Touch) -> None:
        """Store a reference touch; the belief uses every one of them."""
        self.match.add(0, self._describe(touch))

    def heldout_proba(self, x: np.ndarray) -> np.ndarray:
        """(C,) probabilities of the comparison descriptor ``x`` just added, computed by
        ``add_touch`` before it was stored (the held-back check of the engine)."""
        if self._heldout is None:
            raise InputError("no held-back probabilities: the belief was not ready yet")
        return self._heldout

    def reference_probs(self) -> np.ndarray:
        """(T, C) beliefs under posterior draws of the platform means (T = ``DRAWS``)."""
        return self.match.samples(DRAWS, self._rng)

    def belief(self, probs: np.ndarray) -> np.ndarray:
        """(C,) the exact belief (the draws only serve the uncertainty strategies); with a
        fabric library, its known fabrics marginalised in (``LibraryBelief``)."""
        scene = self.match.belief()
        if self.library is None:
            return scene
        means = np.stack([np.mean(s, axis=0) for s in self.match.samples_by_platform])
        return self.library.belief(means, self.match.counts, scene)

    def separation(self) -> float:
        """The two best comparisons' separation (``MatchModel.separation``)."""
        return self.match.separation()

    def info_gain(self, rng: np.random.Generator) -> np.ndarray:
        """(C + 1,) expected entropy drop per platform, 0 = reference (``MatchModel``)."""
        return self.match.info_gain(rng)

    def stop_chance(self, rng: np.random.Generator, theta: float) -> np.ndarray:
        """(2, C + 1) chance of reaching belief ``theta`` within one / two more touches, the
        first of each platform, 0 = reference (``MatchModel.stop_chance``)."""
        return self.match.stop_chance(rng, theta)
