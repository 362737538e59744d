"""Ensemble of heads and last-layer Laplace (tactex_lab/cnn/uncertainty.py): hand-computed values, the
model's heads, and the learner's three uncertainty sources."""

import math

import numpy as np
import pytest
import torch

from tactex_lab.cnn import uncertainty as unc
from tactex_ros.core import strategies
from tactex_ros.core.config import CnnSettings, preset
from tactex_ros.core.errors import InputError
from tactex_lab.cnn.learner import OnlineLearner
from tactex_lab.cnn.models import build_model
from stripes import stripe_frames

FAST = dict(input_size=48, steps=4, batch_size=16, mc_passes=8, threads=1)


# ------------------------------------------------------------------ Laplace, by hand
def test_ggn_of_a_two_class_linear_head_by_hand():
    # one input phi = (1, 2), p = (0.5, 0.5): Lambda = [[.25, -.25], [-.25, .25]],
    # H = Lambda kron phi phi^T, parameters ordered (c, d)
    h = unc.softmax_ggn(torch.tensor([[1.0, 2.0]]), torch.tensor([[0.5, 0.5]]))
    expected = [[0.25, 0.5, -0.25, -0.5],
                [0.5, 1.0, -0.5, -1.0],
                [-0.25, -0.5, 0.25, 0.5],
                [-0.5, -1.0, 0.5, 1.0]]
    np.testing.assert_allclose(h.numpy(), expected, atol=1e-12)
    # two inputs add: p = (0.8, 0.2) gives Lambda = 0.16 [[1, -1], [-1, 1]], phi = (1, 0)
    h2 = unc.softmax_ggn(torch.tensor([[1.0, 2.0], [1.0, 0.0]]),
                         torch.tensor([[0.5, 0.5], [0.8, 0.2]]))
    extra = np.zeros((4, 4))
    extra[np.ix_([0, 2], [0, 2])] = 0.16 * np.array([[1, -1], [-1, 1]])
    np.testing.assert_allclose(h2.numpy(), np.asarray(expected) + extra, atol=1e-12)


def test_laplace_predictive_of_a_two_class_head_with_known_precision():
    # weight (2, 1), bias (2,) as theta (C=2, D=2); precision 4 I -> Sigma = 0.25 I.
    theta = torch.tensor([[0.0, 0.0], [1.0, 0.5]], dtype=torch.float64)
    la = unc.LastLayerLaplace(theta, 4.0 * torch.eye(4, dtype=torch.float64), 4.0)
    x = torch.tensor([[2.0]])                       # phi = (2, 1): mean logits (0, 2.5)
    # J Sigma J^T = 0.25 |phi|^2 I = 1.25 I
    np.testing.assert_allclose(la.logit_cov(x).numpy()[0], 1.25 * np.eye(2), atol=1e-12)
    # p(class 1) = E[sigmoid(f1 - f0)], f1 - f0 ~ N(2.5, 2.5): Gauss-Hermite quadrature
    z, w = np.polynomial.hermite_e.hermegauss(80)
    exact = float(np.sum(w / (1 + np.exp(-(2.5 + math.sqrt(2.5) * z)))) / math.sqrt(2 * math.pi))
    gen = torch.Generator().manual_seed(0)
    probs = la.sample_probs(x, 40000, gen).numpy()
    assert probs.shape == (40000, 2)
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-12)
    assert abs(probs[:, 1].mean() - exact) < 0.005
    # MacKay's probit approximation sigmoid(m / sqrt(1 + pi v / 8)) = 0.855, well below the
    # MAP's sigmoid(2.5) = 0.924
    assert abs(exact - 1 / (1 + math.exp(-2.5 / math.sqrt(1 + math.pi * 2.5 / 8)))) < 0.005
    assert exact < 0.87
    # the draws' logit difference has the variance of J Sigma J^T: 1.25 + 1.25
    diff = np.log(probs[:, 1] / probs[:, 0])
    assert abs(diff.var() - 2.5) < 0.08 and abs(diff.mean() - 2.5) < 0.03
    # seeded: the same generator seed gives the same draws
    again = la.sample_probs(x, 40000, torch.Generator().manual_seed(0)).numpy()
    np.testing.assert_array_equal(probs, again)


def test_marginal_likelihood_by_hand_and_its_maximiser():
    # P = 1 weight, eigenvalue 3, log lik -2, theta^2 = 4, lambda = 1:
    # -2 - 0.5 * 4 + 0.5 log 1 - 0.5 log 4
    assert unc.log_marginal_likelihood(-2.0, 4.0, np.array([3.0]), 1.0) == pytest.approx(
        -4.0 - 0.5 * math.log(4.0))
    # d/dlambda = -theta^2/2 + 1/(2 lambda) - 1/(2 (e + lambda)) = 0 at lambda = 1 when e = 1
    # and theta^2 = 1/(lambda (1 + lambda)) = 0.5
    assert unc.marglik_prior_precision(0.0, 0.5, np.array([1.0])) == pytest.approx(1.0)
    assert 1.0 in unc.PRIOR_GRID


def test_laplace_fit_uses_the_ggn_and_a_tight_posterior_gives_the_map():
    gen = torch.Generator().manual_seed(3)
    feats = torch.randn(30, 5, generator=gen)
    labels = torch.randint(0, 3, (30,), generator=gen)
    w, b = torch.randn(3, 5, generator=gen), torch.randn(3, generator=gen)
    la = unc.LastLayerLaplace.fit(w, b, feats, labels, prior_precision=2.0)
    phi = unc.with_bias(feats.double())
    p = torch.softmax(phi @ la.theta.T, 1)
    np.testing.assert_allclose(la.precision.numpy(),
                               (unc.softmax_ggn(phi, p) + 2.0 * torch.eye(18,
                                                                          dtype=torch.float64)
                                ).numpy(), atol=1e-10)
    tight = unc.LastLayerLaplace.fit(w, b, feats, labels, prior_precision=1e6)
    x = torch.randn(2, 5, generator=gen)
    draws = tight.sample_probs(x, 5, torch.Generator().manual_seed(1)).numpy()
    map_p = torch.softmax(x.double() @ w.double().T + b.double(), 1).mean(0).numpy()
    np.testing.assert_allclose(draws, np.broadcast_to(map_p, draws.shape), atol=5e-3)
    # prior by marginal likelihood: a grid value
    auto = unc.LastLayerLaplace.fit(w, b, feats, labels)
    assert auto.prior_precision in unc.PRIOR_GRID
    with pytest.raises(ValueError, match="prior_precision"):
        unc.LastLayerLaplace.fit(w, b, feats, labels, prior_precision=-1.0)


# ------------------------------------------------------------------ ensemble, by hand
def test_member_disagreement_by_hand():
    # member 0 says (0.25, 0.75), member 1 (0.75, 0.25): logits (0, ln 3) and (ln 3, 0)
    l3 = math.log(3.0)
    table = unc.member_table(torch.tensor([[[0.0, l3], [l3, 0.0]]])).double().numpy()
    np.testing.assert_allclose(table, [[0.25, 0.75], [0.75, 0.25]], atol=1e-6)
    np.testing.assert_allclose(strategies.expected_variance(table), [0.0625, 0.0625], atol=1e-6)
    bald = 0.5 * math.log(2.0) + 0.5 * (0.25 * math.log(0.25) + 0.75 * math.log(0.75))
    np.testing.assert_allclose(strategies.bald_contribution(table), [bald, bald], atol=1e-6)
    # members that agree do not disagree
    same = unc.member_table(torch.tensor([[[0.0, l3], [0.0, l3]]])).double().numpy()
    np.testing.assert_allclose(strategies.expected_variance(same), 0.0, atol=1e-12)
    np.testing.assert_allclose(strategies.bald_contribution(same), 0.0, atol=1e-6)
    # views are averaged per member: (V=2, K=1, C=2)
    two = unc.member_table(torch.tensor([[[0.0, l3]], [[l3, 0.0]]])).double().numpy()
    np.testing.assert_allclose(two, [[0.5, 0.5]], atol=1e-6)


def test_heads_share_the_stem_and_forward_is_the_members_mean_softmax():
    torch.manual_seed(0)
    model, _ = build_model("small_inception", 4, dropout=0.5, heads=3)
    assert model.fc.weight.shape == (12, 192) and model.num_classes == 4
    x = torch.randn(2, 3, 48, 48)
    model.eval()
    with torch.no_grad():
        members = model.member_logits(x)
        assert members.shape == (2, 3, 4)
        np.testing.assert_allclose(torch.softmax(model(x), 1).numpy(),
                                   torch.softmax(members, 2).mean(1).numpy(), atol=1e-6)
        table = unc.ensemble_probs(model, x)
        assert table.shape == (3, 4)
        # heads start from different weights: they disagree
        assert float(strategies.expected_variance(table.double().numpy()).sum()) > 0
        # every member has its own dropout mask in training mode
        k, c = 3, 4
        w = model.fc.weight.view(k, c, -1)
        w[1:] = w[0]
        model.fc.bias.view(k, c)[1:] = model.fc.bias.view(k, c)[0]
        same = model.member_logits(x)
        np.testing.assert_allclose(same[:, 0].numpy(), same[:, 2].numpy(), atol=1e-5)
        model.train()
        for m in model.modules():          # keep batch norm on running statistics
            if isinstance(m, torch.nn.BatchNorm2d):
                m.eval()
        masked = model.member_logits(x)
        assert not torch.allclose(masked[:, 0], masked[:, 2])
    single, _ = build_model("small_inception", 4)
    assert single.fc.weight.shape == (4, 192) and single.heads == 1


# ------------------------------------------------------------------ settings and learner
def test_settings_default_unchanged_and_checked():
    assert CnnSettings().uncertainty == "mc_dropout"
    for name in ("cnn", "seed_faithful"):
        assert preset(name).uncertainty == "mc_dropout"
    with pytest.raises(InputError, match="ensemble_heads"):
        preset("cnn", uncertainty="ensemble", ensemble_heads=1)
    with pytest.raises(InputError, match="ensemble_heads"):
        preset("cnn", uncertainty="ensemble", ensemble_heads=33)
    with pytest.raises(InputError, match="uncertainty"):
        preset("cnn", uncertainty="deep_ensemble")
    with pytest.raises(InputError, match="laplace_prior_precision"):
        preset("cnn", uncertainty="laplace", laplace_prior_precision=-1.0)


@pytest.fixture
def one_thread():
    """The learner's ``threads=1`` sets torch's global thread count: restore it afterwards."""
    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)


@pytest.mark.parametrize("kind,rows", [("ensemble", 4), ("laplace", 8), ("mc_dropout", 8)])
def test_learner_tables_for_each_uncertainty(kind, rows, one_thread):
    cfg = preset("cnn", uncertainty=kind, ensemble_heads=4, **FAST)
    frames = stripe_frames(1, 3)
    tables = []
    for _ in range(2):
        lr = OnlineLearner(3, cfg, seed=5)
        if kind == "ensemble":
            assert lr.model.heads == 4
        for k, f in enumerate(frames):
            lr.add_touch(f, k)
            lr.add_touch(f[::-1].copy(), k)
        lr.add_reference(frames[2])
        if kind == "laplace":
            with pytest.raises(InputError, match="laplace"):
                lr.reference_probs()
        for _ in range(3):
            lr.train_round()
        t = lr.reference_probs()
        assert t.shape == (rows, 3)
        np.testing.assert_allclose(t.sum(axis=1), 1.0, atol=1e-5)
        assert lr.belief(t).shape == (3,)
        tables.append(t)
    np.testing.assert_array_equal(tables[0], tables[1])     # seeded
    if kind == "laplace":
        assert lr.laplace is not None and lr.laplace.prior_precision > 0
        assert lr.laplace.precision.shape == (3 * 193, 3 * 193)


def test_laplace_refuses_a_last_layer_too_large_for_a_full_posterior():
    with pytest.raises(InputError, match="laplace"):
        OnlineLearner(4, preset("cnn", model="inception_v3_random", input_size=75,
                                uncertainty="laplace"), seed=0)
    with pytest.raises(InputError, match="laplace"):
        OnlineLearner(16, preset("cnn", uncertainty="laplace"), seed=0)
    OnlineLearner(15, preset("cnn", uncertainty="laplace"), seed=0)
