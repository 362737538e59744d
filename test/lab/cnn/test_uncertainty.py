import numpy as np
import pytest
import torch
from scipy import stats

from tactex_lab.cnn import uncertainty as unc
from tactex_ros.core import strategies
from tactex_lab.cnn.models import build_model
from tactex_ros.core.strategies import break_ties, make_strategy
from tactex_ros.core.errors import InputError


def test_batched_passes_equal_sequential_in_distribution():
    torch.manual_seed(0)
    model, _ = build_model("small_inception", 4, dropout=0.5)
    x = torch.randn(1, 3, 75, 75)
    batched = unc.mc_probs(model, x, 2000, generator=torch.Generator().manual_seed(1)).numpy()
    seq = []
    model.train()
    for m in model.modules():  # eval BN, active dropout, one pass at a time
        if isinstance(m, torch.nn.BatchNorm2d):
            m.eval()
    torch.manual_seed(2)
    with torch.no_grad():
        for _ in range(2000):
            seq.append(torch.softmax(model(x), 1)[0].numpy())
    seq = np.array(seq)
    assert batched.shape == seq.shape == (2000, 4)
    for c in range(4):  # same distribution per class probability (two-sample KS)
        assert stats.ks_2samp(batched[:, c], seq[:, c]).pvalue > 0.01
    np.testing.assert_allclose(batched.mean(0), seq.mean(0), atol=0.02)
    assert batched.std(0).min() > 0  # dropout really is active


def test_scores_on_hand_computed_table():
    p = np.array([[0.7, 0.1, 0.1, 0.1],
                  [0.3, 0.5, 0.1, 0.1]])
    np.testing.assert_allclose(strategies.expected_variance(p), [0.04, 0.04, 0, 0])
    pbar = np.array([0.5, 0.3, 0.1, 0.1])
    np.testing.assert_allclose(strategies.entropy_contribution(p), -pbar * np.log(pbar), atol=1e-9)
    bald = strategies.bald_contribution(p)
    mi = -(pbar * np.log(pbar)).sum() + (p * np.log(p)).sum(1).mean()
    assert bald.sum() == pytest.approx(mi) and np.all(bald >= 0)
    np.testing.assert_allclose(bald[2:], 0, atol=1e-12)


def test_each_strategy_choice_on_constructed_tables():
    touches = np.array([1, 1, 1, 1])
    rng = np.random.default_rng(0)
    # platform 2 (index 2) flips between passes: highest variance
    var_tab = np.array([[0.1, 0.1, 0.7, 0.1], [0.1, 0.1, 0.1, 0.7], [0.1, 0.1, 0.7, 0.1]])
    assert make_strategy("variance").choose(var_tab, touches, rng)[0] == 2
    # entropy contribution -p log p peaks at p = 1/e: platform with mean 0.37 wins over 0.9
    ent_tab = np.array([[0.37, 0.53, 0.05, 0.05]])
    assert make_strategy("entropy").choose(ent_tab, touches, rng)[0] == 0
    # bald: disagreement between passes on platforms 0/1, agreement on 2/3
    bald_tab = np.array([[0.9, 0.05, 0.03, 0.02], [0.05, 0.9, 0.03, 0.02]])
    assert make_strategy("bald").choose(bald_tab, touches, rng)[0] in (0, 1)
    assert make_strategy("yoto").choose(var_tab, touches, rng) == (None, None)
    picks = [make_strategy("random").choose(var_tab, touches, np.random.default_rng(s))[0]
             for s in range(400)]
    counts = np.bincount(picks, minlength=4)
    assert stats.chisquare(counts).pvalue > 0.001 and counts.min() > 60


def test_ties_go_to_least_touched_then_lowest_index():
    assert break_ties(np.array([0.2, 0.2, 0.2]), np.array([3, 1, 1])) == 1
    assert break_ties(np.array([0.2, 0.5, 0.5]), np.array([0, 4, 2])) == 2
    assert break_ties(np.array([np.nan, 0.1, 0.0]), np.array([0, 0, 0])) == 1
    # all scores equal -> round-robin over the least touched, not always platform 0
    t = np.zeros(4, int)
    seq = []
    for _ in range(8):
        i = break_ties(np.zeros(4), t)
        seq.append(i)
        t[i] += 1
    assert seq == [0, 1, 2, 3, 0, 1, 2, 3]


def test_unknown_strategy_is_named():
    with pytest.raises(InputError, match="greedy"):
        make_strategy("greedy")
