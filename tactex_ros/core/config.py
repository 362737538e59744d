"""The settings: learner, trial, presets (on the schema machinery of ``core/schema.py``).

The learner settings (``LearnerSettings``: a discriminated union on ``model`` of
``DescriptorSettings``, ``CnnSettings``, ``AutoSettings`` and ``LadderSettings``),
``TrialConfig`` (what a trial does) and the named presets live here; ``TrialSettings``
composes a preset with overrides of both, and is what the command line and the explorer node
(``ExplorerSettings``) are made of.
"""

from __future__ import annotations

import typing
from typing import Annotated, Any, ClassVar, Literal, Union

from pydantic import Field, TypeAdapter, ValidationError, model_validator

from .errors import InputError
from .schema import TAG, FieldError, Schema, located, param

# the CNN learners (the thesis method) are a plug-in (``core/learners.py``): the schema names them,
# the lab implements them
CNN_MODELS = ("small_inception", "inception_v3", "inception_v3_random")
# the strategies of core/strategies.py (STRATEGIES; a test keeps the two equal): named here so
# that the schema, and with it `tactex trial --help`, imports no numpy
STRATEGY_NAMES = ("variance", "entropy", "random", "yoto", "bald", "infogain", "lookahead")
# ... and those that may touch the reference again (``Strategy.includes_reference``): they
# need a learner whose belief takes reference touches (``LearnerBase.scores_reference``)
REFERENCE_STRATEGIES = ("infogain", "lookahead")
MODEL_NAMES = ("descriptor",) + CNN_MODELS + ("cnn_auto", "auto")
MODEL_HELP = ("model: 'descriptor' (texture descriptor + Gaussian match belief, no training), "
              "a CNN variant, 'auto' (a ladder: descriptor, then the prepared representation, "
              "then a CNN, climbed only on the trial's evidence, core/ladder.py) or 'cnn_auto' "
              "(the same ladder over CNN sizes); it picks the learner's settings (a descriptor has no "
              "CNN setting)")


class LearnerBase(Schema):
    """What every learner's settings have: its name (``model``, the union's tag) and the
    engine's contact guards. A subclass per learner; ``LearnerSettings`` is their union."""

    kind: ClassVar[str] = ""      # the learner family: 'descriptor', 'cnn', 'cnn_auto', 'auto'
    # capabilities (what code asks instead of testing ``model``): a learner of a
    # ``tactex.learners`` plug-in named by ``model`` (``core/build.py`` loads it) ...
    plugin: ClassVar[bool] = False
    # ... or a ladder of learners (``core/ladder.py``; its rungs are built by ``make_learner``)
    is_ladder: ClassVar[bool] = False
    # capability: its belief takes touches of the reference too, so a strategy that scores the
    # reference (``Strategy.includes_reference``, infogain) can run with it
    scores_reference: ClassVar[bool] = False
    model: str
    guards: bool = param(True, "failure-mode guards on: reject blank / no-contact touches, "
                               "clip gradients and skip non-finite steps, tie-break degenerate "
                               "scores (False = the unguarded behaviour, for before/after runs)")
    contact_flat_min: float = param(0.35, "reject a touch whose texture (blur5 - blur_sigma8, "
                                          "grey levels) is below this: a flat frame (0 = off)",
                                    0.0, 50.0)
    contact_min: float = param(0.8, "reject a touch whose contact score against the session's "
                                    "no-contact reference is below this [grey levels] (0 = off; "
                                    "needs TrialEngine.set_no_contact_reference)", 0.0, 50.0)

    def as_model(self, model: str, **kw: Any) -> LearnerSettings:
        """The settings of learner ``model`` (maybe of another family) with this one's values
        of the fields that learner has, and ``kw``; validated."""
        cls = learner_class(model)
        mine = {k: v for k, v in self.model_dump().items() if k in cls.model_fields}
        return cls.check({**mine, "model": model, **kw}, cls.__name__)


class DescriptorSettings(LearnerBase):
    """The shipped learner (``core/descriptor.py``): texture descriptors and a calibrated
    Gaussian match belief; nothing is trained. The class defaults are the shipped method's."""

    kind: ClassVar[str] = "descriptor"
    scores_reference: ClassVar[bool] = True
    model: Literal["descriptor"] = param("descriptor", MODEL_HELP)
    descriptor_frames: int = param(1, "model 'descriptor': contact frames of one press averaged "
                                      "into its descriptor (the strongest + more of the press; "
                                      "the height map is the strongest frame's)",
                                   1, 16)
    descriptor_height_map: bool = param(
        True, "model 'descriptor': append the contact's height-map statistics (photometric "
              "stereo without calibration, 23 numbers; core/texture.py) to the descriptor "
              "(129 numbers; off: the 106-number descriptor of earlier releases). Representation "
              "files and fabric libraries hold descriptors of one size: prepare them with the "
              "same setting")
    descriptor_embedding: str = param(
        "sim", "model 'descriptor': append a learned embedding of the contact frames (128 "
            "numbers, the mean over descriptor_embedding_frames; core/embedding.py, numpy): "
            "'sim' = the "
            "shipped network trained on the simulator's fabrics only, a path = a weights file "
            "the lab exported, '' = none. Representation files and fabric libraries hold "
            "descriptors of one embedding: prepare them with the same setting")
    descriptor_embedding_frames: int = param(
        4, "model 'descriptor': contact frames of one press whose embeddings are averaged (the "
           "strongest and the next of its burst, press.capture_frames; a touch with fewer uses "
           "those it has); the descriptor itself takes descriptor_frames", 1, 16)
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
    representation_temperature: bool = param(
        True, "model 'descriptor': use the belief temperature `tactex prepare` calibrated on the "
              "library with classes left out, when the representation file has one (else "
              "match_temperature)")
    match_units: Literal["scene", "fixed"] = param(
        "scene", "model 'descriptor': units of the belief: 'scene' (each dimension divided by "
                 "its spread over this scene's platforms) or 'fixed' (as given, e.g. by a "
                 "representation)")
    match_temperature: float = param(
        0.0251, "model 'descriptor': temperature on the log evidence (calibrates the belief): "
                "0.0251 = 0.05 x 129 / 257, the evidence per number of the 129-number "
                "descriptor's 0.05, for the 257 numbers with the shipped embedding; without an "
                "embedding (descriptor_embedding='') use 0.05", 1e-4, 10.0)
    contact_region_min: float = param(0.0, "model 'descriptor': a touch whose contact region "
                                           "(against its own no-contact frame) covers less than "
                                           "this share of the frame is a partial contact and is "
                                           "described over its region only (0 = off; "
                                           "core/guards.py)", 0.0, 1.0)
    fabric_library: bool = param(
        True, "model 'descriptor': in a session, the belief also asks the session's fabric "
              "library (<session folder>/fabric_library.npz: the presses of every earlier trial "
              "whose placement was known, under their fabric names) which known fabric each "
              "platform holds, and each finished trial's presses join it (core/library.py; "
              "off: the scene-only belief, the thesis protocol)")
    # match_temperature 0.05, match_prior_scale 1.0, descriptor_frames 1 and the stop at 0.9
    # were chosen in every one of 3 class folds of octopi-dev (docs/research/real_presses.md);
    # descriptor_height_map on: fewer touches at equal accuracy on classes the settings never
    # saw, both directions, 2 seeds (issue 33, docs/research/unseen_materials.md);
    # descriptor_embedding 'sim' with match_temperature 0.0251: more accurate on classes the
    # settings never saw, both directions, 3 networks x 3 seeds; the network was trained on
    # the simulator's fabrics only (issue 33, same page, "A network trained on the simulator's
    # fabrics"); descriptor_embedding_frames 4: fewer touches at equal accuracy on classes the
    # settings never saw, both directions, 3 seeds (same page, "The embedding of the burst")


#: ``learner.device``: its allowed forms (whether the device exists is checked by the lab,
#: where torch is imported: tactex_lab/cnn/device.py).
DEVICE_PATTERN = r"^(cpu|cuda|cuda:[0-9]+|auto)$"
DEVICE_HELP = ("torch device of a CNN's model, optimiser, stored views and MC passes: 'cpu', "
               "'cuda', 'cuda:N' (GPU N) or 'auto' (the first GPU torch sees, else the CPU); "
               "an absent GPU is refused before the trial")


class CnnSettings(LearnerBase):
    """A thesis CNN (a plug-in of group ``tactex.learners``, ``tactex_lab/cnn/learner.py``):
    trained between decisions, Monte-Carlo dropout or another uncertainty. The schema is
    pure pydantic, so the product validates, declares and documents it without torch."""

    kind: ClassVar[str] = "cnn"
    plugin: ClassVar[bool] = True
    model: Literal[CNN_MODELS] = param("small_inception", MODEL_HELP)  # type: ignore[valid-type]  # pydantic reads it at run time
    input_size: int = param(299, "model input side [px]", 32, 512)
    augment: int = param(10, "random-rotation views stored per touch", 1, 64)
    sensor_crops: bool = param(False, "views are input_size px crops of the frame at sensor "
                                      "resolution at random positions (no down-scaling; "
                                      "input_size <= 169) instead of the centre square resized "
                                      "to input_size")
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
    mc_passes: int = param(20, "Monte-Carlo dropout passes per decision (uncertainty "
                               "'laplace': posterior draws per decision)", 1, 1000)
    uncertainty: Literal["mc_dropout", "ensemble", "laplace"] = param(
        "mc_dropout", "CNN uncertainty (tactex_lab/cnn/uncertainty.py): 'mc_dropout' (mc_passes stochastic "
                      "passes), 'ensemble' (ensemble_heads heads over the shared stem, their "
                      "disagreement) or 'laplace' (last-layer Laplace posterior, mc_passes "
                      "draws; small_inception with at most 15 comparisons)")
    ensemble_heads: int = param(5, "uncertainty 'ensemble': number of heads K", 2, 32)
    laplace_prior_precision: float = param(0.0, "uncertainty 'laplace': prior precision of the "
                                                "last layer's weights (0 = chosen by the "
                                                "marginal likelihood on a grid 1e-4..1e4)",
                                           0.0, 1e6)
    test_views: int = param(1, "views of the reference averaged when scoring (1 = unrotated)",
                            1, 64)
    aux_logits: bool = param(False, "train Inception v3's auxiliary classifier too")
    fourier: bool = param(False, "train on log-magnitude Fourier spectra of the views")
    weights: str = param("", "torchvision-format checkpoint for inception_v3 ('' = none)")
    bn_recalibrate: int = param(64, "after each round, re-estimate batch-norm statistics on up to "
                                    "this many stored views (0 = keep running averages)",
                                0, 100000)
    threads: int = param(0, "torch intra-op threads (0 = leave torch's default)", 0, 256)
    device: str = param("cpu", DEVICE_HELP, pattern=DEVICE_PATTERN)
    deterministic: bool = param(True, "on a CUDA device: torch's deterministic kernels where it "
                                      "has them (tactex_lab/cnn/device.py), so a seeded trial "
                                      "repeats; off = cuDNN picks the fastest (no effect on "
                                      "the CPU)")
    channels_last: bool = param(True, "channels-last memory format for the model and stored "
                                      "views (same results, faster CPU convolutions)")
    # Guards against the failure modes of `tactex experiment stability` (core/guards.py).
    grad_clip: float = param(5.0, "clip the gradient norm to this (0 = off)", 0.0, 1e6)
    drift_norm: bool = param(False, "remove each touch's per-channel mean colour before the "
                                    "model sees it: turn on where the lighting drifts between "
                                    "touches (measured: it restores accuracy under drift in "
                                    "simulation, and cost 2 of 24 replayed octopi-dev scenes, "
                                    "docs/research/speed_stability.md)")
    # model 'cnn_auto': start cheap, escalate on evidence (core/ladder.py). The first
    # stage is the cheapest that works: 32 px lost 19 points against 48 px in the pareto grid
    # (docs/research/speed_stability.md), and a 32 px start made it 9 points worse than the default.


class AutoSettings(CnnSettings):
    """Model 'cnn_auto': the ladder of ``core/ladder.py`` whose rungs are CNNs (``auto_ladder``,
    each rung with the CNN settings here at its input size), climbed by the ``auto_*`` rule
    (held-back touches, then a reference entropy that does not fall)."""

    kind: ClassVar[str] = "cnn_auto"
    plugin: ClassVar[bool] = False
    is_ladder: ClassVar[bool] = True
    model: Literal["cnn_auto"] = param("cnn_auto", MODEL_HELP)
    auto_ladder: str = param("small_inception@48,small_inception@96",
                             "model 'cnn_auto': stages cheapest first, 'model@input_px' "
                             "separated by commas ('model' alone = input_size)")
    auto_patience: int = param(2, "model 'cnn_auto': rounds on a stage before the entropy test",
                               1, 1000)
    auto_min_drop: float = param(0.7, "model 'cnn_auto': escalate when predictive entropy fell by "
                                      "less than this fraction over the last auto_patience rounds",
                                 0.0, 1.0)
    auto_entropy: float = param(0.2, "model 'cnn_auto': ... and is still above this fraction of "
                                     "log(C)", 0.0, 1.0)
    auto_window: int = param(3, "model 'cnn_auto': held-back touches judged together", 1, 1000)
    auto_heldout_acc: float = param(0.5, "model 'cnn_auto': escalate when fewer than this share of "
                                         "the last auto_window touches were classified right "
                                         "before being trained on", 0.0, 1.0)
    auto_catchup: int = param(3, "model 'cnn_auto': extra training rounds given at once to an "
                                 "escalated model (at most the rounds trained so far)", 0, 100)



class LadderSettings(DescriptorSettings):
    """Model 'auto' (``core/ladder.py``, docs/research/unseen_materials.md "A ladder of models"): the
    descriptor's settings (its rungs 'descriptor' and 'representation' run with them) and the
    ladder's; a CNN rung runs with its preset's settings."""

    kind: ClassVar[str] = "auto"
    is_ladder: ClassVar[bool] = True
    model: Literal["auto"] = param("auto", MODEL_HELP)
    ladder: str = param("descriptor,representation,cnn",
                        "model 'auto': rungs cheapest first, separated by commas: 'descriptor', "
                        "'representation' (skipped without a representation file) or a preset "
                        "with a trained model ('cnn'), optionally '@px'")
    ladder_patience: int = param(2, "model 'auto': decisions on a rung before its evidence is "
                                    "tested; the belief-sharpening test spans this many",
                                 1, 1000)
    ladder_min_gain: float = param(0.1, "model 'auto': climb when the leading belief rose by "
                                        "less than this over ladder_patience decisions ...",
                                   0.0, 1.0)
    ladder_sure: float = param(0.9, "model 'auto': ... while it is below this", 0.0, 1.0)
    ladder_margin: float = param(0.1, "model 'auto': climb when the best two beliefs differ by "
                                      "less than this (and the leader is below ladder_sure)",
                                 0.0, 1.0)
    ladder_window: int = param(3, "model 'auto': held-back touches judged together", 1, 1000)
    ladder_heldout_acc: float = param(0.5, "model 'auto': climb when fewer than this share of "
                                           "the last ladder_window comparison touches were "
                                           "classified right before being stored", 0.0, 1.0)
    ladder_catchup: int = param(3, "model 'auto': training rounds given at once to a trained "
                                   "rung when it is reached (at most the decisions so far)",
                                0, 100)
    threads: int = param(0, "model 'auto': torch intra-op threads of a CNN rung (0 = leave "
                            "torch's default)", 0, 256)
    device: str = param("cpu", "model 'auto': " + DEVICE_HELP + " (its CNN rung)",
                        pattern=DEVICE_PATTERN)


#: The learners' settings: one class per family, told apart by ``model`` (a discriminated
#: union). A descriptor's settings carry no CNN field, and a CNN field given to it is refused.
# Union, not A | B: schema.variants and mypy (located(..., cls: type)) take typing.Union
LearnerSettings = Annotated[Union[DescriptorSettings, CnnSettings, AutoSettings,  # noqa: UP007
                                  LadderSettings], Field(discriminator="model")]
LEARNER_CLASSES: tuple[type, ...] = (DescriptorSettings, CnnSettings, AutoSettings,
                                     LadderSettings)
_LEARNERS = TypeAdapter(LearnerSettings)


def learner_class(model: str) -> type:
    """The settings class of learner ``model``; InputError names the known models."""
    for cls in LEARNER_CLASSES:
        if model in typing.get_args(cls.model_fields["model"].annotation):
            return cls
    raise InputError(f"model {model!r}: choose one of {', '.join(MODEL_NAMES)}")


def learner_settings(data: dict[str, Any], origin: str = "learner") -> Any:
    """``data`` (a mapping; ``model`` picks the class, default 'descriptor') validated into
    its learner's settings; InputError names every bad field as ``origin: field: problem``."""
    data = {"model": "descriptor", **data}
    try:
        return _LEARNERS.validate_python(data)
    except ValidationError as exc:
        raise located(exc, origin, LearnerSettings) from None


#: The shipped stop rule's threshold on the belief, chosen on real presses in every one of 3
#: class folds of octopi-dev (docs/research/real_presses.md); ``stop_reason`` (core/engine.py) applies it.
SHIPPED_STOP = 0.9


class TrialConfig(Schema):
    """What a trial does (the learner's settings are LearnerSettings). The defaults are the
    shipped method's: information-gain touches, stop at belief ``SHIPPED_STOP``."""

    strategy: Literal[STRATEGY_NAMES] = param("infogain", "exploration strategy")  # type: ignore[valid-type]  # pydantic reads it at run time
    rounds: int = param(20, "decisions that request a touch after the baseline", 0, 1000)
    stop_confidence: float = param(SHIPPED_STOP, "stop once the belief in one comparison "
                                                 "reaches this (0 = never: all rounds)", 0.0, 1.0)
    stop_separation: float = param(
        0.0, "not sure while the two best comparisons are alike: the stop also needs their "
             "means' separation (core/match.py: squared distance over its sampling spread per "
             "dimension, 1 = as alike as repeated touches of one platform) above this; a trial "
             "whose budget ends below it ends not sure (0 = off; descriptor models)", 0.0, 1e6)
    stop_rule: Literal["threshold", "evalue"] = param(
        "threshold", "threshold (stop at belief stop_confidence) or evalue (stop when one "
                     "comparison's likelihood-ratio e-value reaches 1 / stop_alpha: P(ever "
                     "stopping wrong) <= stop_alpha under the evidence model, core/evidence.py;"
                     " descriptor models)")
    stop_alpha: float = param(0.03, "stop_rule evalue: the bound on the chance of ever "
                                    "stopping wrong (stop at e-value 1 / stop_alpha)",
                              1e-6, 0.5)
    stop_null: Literal["library", "scene"] = param(
        "library", "stop_rule evalue: the null's distance between different materials: the "
                   "evidence model's (library), or also the trial's own touches of two "
                   "comparisons, the closer of the two (scene; core/evidence.py)")
    max_touches: int = param(0, "cap on total touches incl. baseline (0 = no cap)", 0, 100000)
    baseline_passes: int = param(5, "passes over platforms whose baseline touch failed before "
                                    "the trial gives up", 1, 100)
    touch_retries: int = param(2, "a touch that fails or that the contact guard rejects is "
                                  "repeated at once up to this many times before its round "
                                  "counts as lost", 0, 20)


# The thesis's setting, kept by name for reproductions; the CNN setting chosen by
# `tactex bench latency` / `tactex experiment pareto` on the simulator
# (docs/research/speed_stability.md); and the default, chosen on real presses (`tactex
# experiment real`, docs/research/real_presses.md).
PRESETS: dict[str, dict[str, Any]] = {
    "default": dict(),          # the class defaults (DescriptorSettings) are the shipped method
    # the 129-number descriptor alone, no network (the default before the embedding, issue 33):
    # its belief temperature is the one chosen for it on octopi-dev
    "descriptor": dict(descriptor_embedding="", match_temperature=0.05),
    "seed_faithful": dict(model="small_inception", input_size=299, epochs=10, steps=0,
                          batch_size=32, lr=1e-3, dropout=0.5, mc_passes=20,
                          bn_recalibrate=0),
    # 48 px and 8 steps per round since issue 5 (was 64 px, 12 steps): 2.8x less CPU per
    # decision at equal or better accuracy (docs/research/speed_stability.md).
    "cnn": dict(model="small_inception", input_size=48, epochs=0, steps=8,
                batch_size=32, lr=3e-3, dropout=0.5, mc_passes=20),
}
# What a trial does under each preset (TrialConfig fields); the default stops on a calibrated
# belief and picks touches by expected information about the match (docs/research/real_presses.md).
TRIAL_PRESETS: dict[str, dict[str, Any]] = {
    "default": dict(),          # the class defaults of TrialConfig are the shipped method
    "descriptor": dict(),
    "seed_faithful": dict(strategy="variance", stop_confidence=0.0),
    "cnn": dict(strategy="variance", stop_confidence=0.0),
}


def _known_preset(name: str) -> None:
    if name not in PRESETS:
        raise InputError(f"unknown configuration {name!r}; choose one of {', '.join(PRESETS)}")


def preset_learner(name: str, given: dict[str, Any] | None = None) -> dict[str, Any]:
    """The learner settings (a mapping, not yet validated) of preset ``name`` with ``given``
    on top. When ``given`` names another family's ``model``, the preset's values that family
    does not have are left out (``--config seed_faithful --model descriptor``); ``given``
    itself is kept whole, so a field its learner lacks is refused by name."""
    base, given = PRESETS[name], dict(given or {})
    model = given.get(TAG, base.get(TAG, "descriptor"))
    try:
        known = learner_class(model).model_fields
    except InputError:
        known = {}                 # the check names the bad model
    return {**{k: v for k, v in base.items() if k in known}, TAG: model, **given}


def preset(name: str, **overrides: Any) -> Any:
    """A named configuration's learner settings with optional overrides, validated."""
    _known_preset(name)
    return learner_settings(preset_learner(name, overrides), f"configuration {name!r}")


def trial_preset(name: str, **overrides: Any) -> TrialConfig:
    """The TrialConfig of a named preset with overrides, validated.

    Overrides whose value is None are ignored (an option the user did not give)."""
    _known_preset(name)
    kw = {**TRIAL_PRESETS[name], **{k: v for k, v in overrides.items() if v is not None}}
    return TrialConfig.check(kw, f"configuration {name!r}")


class TrialSettings(Schema):
    """What one trial runs with: a preset (``config``) and overrides of its learner and trial
    settings. A field of ``learner`` / ``trial`` not given takes the preset's value."""

    config: Literal[tuple(PRESETS)] = param(  # type: ignore[valid-type]  # pydantic reads it at run time
        "default", "named preset of learner and trial settings: default (texture descriptor "
                   "and the shipped embedding, information-gain touches, stop at belief "
                   f"{SHIPPED_STOP:g}), descriptor (the same without the embedding: the "
                   "129-number descriptor at temperature 0.05), cnn, seed_faithful",
        read_only=True)
    learner: LearnerSettings = Field(default_factory=DescriptorSettings)
    trial: TrialConfig = Field(default_factory=TrialConfig)

    @model_validator(mode="after")
    def _strategy_fits_the_learner(self) -> TrialSettings:
        if self.trial.strategy in REFERENCE_STRATEGIES and not self.learner.scores_reference:
            raise FieldError("trial.strategy", f"{self.trial.strategy!r} touches the reference "
                                               f"again and needs model 'descriptor' (got "
                                               f"{self.learner.model!r}); with a CNN model "
                                               "choose another strategy, e.g. variance")
        return self

    @model_validator(mode="before")
    @classmethod
    def _from_preset(cls, data: Any) -> Any:
        if not isinstance(data, dict) or data.get("config", "default") not in PRESETS:
            return data           # the field checks name what is wrong
        name = data.get("config", "default")
        out = dict(data)
        given = data.get("learner")
        if given is None or isinstance(given, dict):
            out["learner"] = preset_learner(name, given)
        given = data.get("trial")
        if given is None or isinstance(given, dict):
            out["trial"] = {**TRIAL_PRESETS[name], **(given or {})}
        return out
