"""Learner and trial settings: one declarative schema per parameter, named presets.

Each field carries ``type``, default, allowed range or choices and a description in its metadata
(the idea of generate_parameter_library). ``validate`` checks a config against it and the ROS nodes
declare their parameters from the same schema.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .errors import TactexError
from .names import MODEL_NAMES


def param(default: Any, description: str, lo: float | None = None, hi: float | None = None,
          choices: tuple | None = None) -> Any:
    """A dataclass field with its schema (range [lo, hi] or choices, description)."""
    return field(default=default, metadata={"description": description, "lo": lo, "hi": hi,
                                            "choices": choices})


@dataclass
class LearnerConfig:
    """How the online learner trains and scores (units in the descriptions)."""

    model: str = param("small_inception", "model: 'descriptor' (texture descriptor + Gaussian "
                                          "match belief, no training), a CNN variant, or "
                                          "'auto' (escalating CNN chooser)",
                       choices=("descriptor",) + MODEL_NAMES + ("auto",))
    input_size: int = param(299, "model input side [px]", 32, 512)
    augment: int = param(10, "random-rotation views stored per touch", 1, 64)
    epochs: int = param(10, "full passes over all stored views per round (when steps == 0)",
                        0, 100)
    steps: int = param(0, "if > 0: minibatch steps per round instead of epochs (constant cost)",
                       0, 10000)
    batch_size: int = param(32, "training minibatch size", 2, 1024)
    lr: float = param(1e-3, "Adam learning rate", 1e-6, 1.0)
    weight_decay: float = param(0.0, "Adam weight decay", 0.0, 1.0)
    dropout: float = param(0.5, "dropout rate before the classifier", 0.0, 0.95)
    block_dropout: float = param(0.0, "dropout rate after stem and Inception blocks (0 = off)",
                                 0.0, 0.95)
    mc_passes: int = param(20, "Monte-Carlo dropout passes per decision", 1, 1000)
    test_views: int = param(1, "views of the reference averaged when scoring (1 = unrotated)",
                            1, 64)
    aux_logits: bool = param(False, "train Inception v3's auxiliary classifier too")
    fourier: bool = param(False, "train on log-magnitude Fourier spectra of the views")
    weights: str = param("", "torchvision-format checkpoint for inception_v3 ('' = none)")
    bn_recalibrate: int = param(64, "after each round, re-estimate batch-norm statistics on up to "
                                    "this many stored views (0 = keep running averages)",
                                0, 100000)
    threads: int = param(0, "torch intra-op threads (0 = leave torch's default)", 0, 256)
    channels_last: bool = param(True, "channels-last memory format for the model and stored "
                                      "views (same results, faster CPU convolutions)")
    # Guards against the failure modes of `tactex experiment stability` (core/guards.py).
    guards: bool = param(True, "failure-mode guards on: reject blank / no-contact touches, "
                               "clip gradients and skip non-finite steps, tie-break degenerate "
                               "scores (False = the unguarded behaviour, for before/after runs)")
    contact_flat_min: float = param(0.35, "reject a touch whose texture (blur5 - blur_sigma8, "
                                          "grey levels) is below this: a flat frame (0 = off)",
                                    0.0, 50.0)
    contact_min: float = param(0.8, "reject a touch whose contact score against the session's "
                                    "no-contact reference is below this [grey levels] (0 = off; "
                                    "needs TrialEngine.set_no_contact_reference)", 0.0, 50.0)
    grad_clip: float = param(5.0, "clip the gradient norm to this (0 = off)", 0.0, 1e6)
    drift_norm: bool = param(False, "remove each touch's per-channel mean colour before the model "
                                    "sees it (robust to lighting drift; off = absolute colour)")
    # model 'auto': start cheap, escalate on evidence (core/engine.py, "Model auto"). The first
    # stage is the cheapest that works: 32 px lost 19 points against 48 px in the pareto grid
    # (docs/speed_stability.md), and a 32 px start made auto 9 points worse than the default.
    auto_ladder: str = param("small_inception@48,small_inception@96",
                             "model 'auto': stages cheapest first, 'model@input_px' separated by "
                             "commas ('model' alone = input_size)")
    auto_patience: int = param(2, "model 'auto': rounds on a stage before the entropy test",
                               1, 1000)
    auto_min_drop: float = param(0.7, "model 'auto': escalate when predictive entropy fell by "
                                      "less than this fraction over the last auto_patience rounds",
                                 0.0, 1.0)
    auto_entropy: float = param(0.2, "model 'auto': ... and is still above this fraction of "
                                      "log(C)", 0.0, 1.0)
    auto_window: int = param(3, "model 'auto': held-back touches judged together", 1, 1000)
    auto_heldout_acc: float = param(0.5, "model 'auto': escalate when fewer than this share of "
                                         "the last auto_window touches were classified right "
                                         "before being trained on", 0.0, 1.0)
    auto_catchup: int = param(3, "model 'auto': extra training rounds given at once to an "
                                 "escalated model (at most the rounds trained so far)", 0, 100)

    # model 'descriptor' (core/texture.py, core/match.py); chosen on real presses
    # (docs/real_presses.md)
    descriptor_frames: int = param(1, "model 'descriptor': contact frames of one press averaged "
                                      "into its descriptor (the strongest + more of the press)",
                                   1, 16)
    match_prior_scale: float = param(1.0, "model 'descriptor': prior within-platform spread of a "
                                          "descriptor, as a fraction of the scene's spread",
                                     1e-3, 10.0)
    match_prior_strength: float = param(4.0, "model 'descriptor': weight of that prior in "
                                             "pseudo-touches", 1e-3, 1000.0)
    descriptor_no_contact: bool = param(True, "model 'descriptor': describe the contact minus "
                                              "the sensor's no-contact frame when the touch has "
                                              "one (off: against a blur of the contact frame)")
    representation: str = param("", "model 'descriptor': a representation file made by "
                                    "`tactex prepare` (a metric learnt from presses of other "
                                    "materials; '' = none)")
    match_units: str = param("scene", "model 'descriptor': units of the belief: 'scene' (each "
                                      "dimension divided by its spread over this scene's "
                                      "platforms) or 'fixed' (as given, e.g. by a "
                                      "representation)", choices=("scene", "fixed"))
    match_temperature: float = param(0.05, "model 'descriptor': temperature on the log evidence "
                                           "(calibrates the belief)", 1e-4, 10.0)
    # match_temperature 0.05, match_prior_scale 1.0, descriptor_frames 1 and the stop at 0.9
    # were chosen in every one of 3 class folds of octopi-dev (docs/real_presses.md)

    def replace(self, **kw: Any) -> "LearnerConfig":
        return validate(dataclasses.replace(self, **kw))


# The thesis's setting, kept by name for reproductions; the CNN setting chosen by
# `tactex bench latency` / `tactex experiment pareto` on the simulator (see README, "Speed");
# and the default, chosen on real presses (`tactex evaluate`, docs/real_presses.md).
PRESETS: dict[str, dict[str, Any]] = {
    "default": dict(model="descriptor"),
    "seed_faithful": dict(model="small_inception", input_size=299, epochs=10, steps=0,
                          batch_size=32, lr=1e-3, dropout=0.5, mc_passes=20,
                          bn_recalibrate=0),
    # 48 px and 8 steps per round since issue 5 (was 64 px, 12 steps): 2.8x less CPU per
    # decision at equal or better accuracy (docs/speed_stability.md).
    "cnn": dict(model="small_inception", input_size=48, epochs=0, steps=8,
                batch_size=32, lr=3e-3, dropout=0.5, mc_passes=20),
}
# What a trial does under each preset (TrialConfig fields); the default stops on a calibrated
# belief and picks touches by expected information about the match (docs/real_presses.md).
TRIAL_PRESETS: dict[str, dict[str, Any]] = {
    "default": dict(strategy="infogain", stop_confidence=0.9),
    "seed_faithful": dict(strategy="variance", stop_confidence=0.0),
    "cnn": dict(strategy="variance", stop_confidence=0.0),
}


def preset(name: str, **overrides: Any) -> LearnerConfig:
    """A named configuration with optional overrides, validated."""
    if name not in PRESETS:
        raise TactexError(f"unknown configuration {name!r}; choose one of {', '.join(PRESETS)}")
    return validate(LearnerConfig(**{**PRESETS[name], **overrides}))


def validate(cfg: Any) -> Any:
    """Check every field of a schema dataclass: type, range, choices. Returns ``cfg``."""
    for f in dataclasses.fields(cfg):
        v = getattr(cfg, f.name)
        want = f.type if isinstance(f.type, type) else {"int": int, "float": float, "str": str,
                                                         "bool": bool}.get(str(f.type), object)
        if want is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
            setattr(cfg, f.name, v)
        if want is not object and (not isinstance(v, want) or
                                   (want is int and isinstance(v, bool))):
            raise TactexError(f"{type(cfg).__name__}.{f.name}: expected {want.__name__}, "
                              f"got {v!r}")
        md = f.metadata
        if md.get("choices") and v not in md["choices"]:
            raise TactexError(f"{type(cfg).__name__}.{f.name}: {v!r} is not one of "
                              f"{', '.join(map(str, md['choices']))}")
        if md.get("lo") is not None and v < md["lo"]:
            raise TactexError(f"{type(cfg).__name__}.{f.name}: {v!r} is below {md['lo']}")
        if md.get("hi") is not None and v > md["hi"]:
            raise TactexError(f"{type(cfg).__name__}.{f.name}: {v!r} is above {md['hi']}")
    return cfg
