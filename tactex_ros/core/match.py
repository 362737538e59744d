"""Belief over which comparison platform matches the reference, from texture descriptors.

The question of a trial is "which of the C comparison platforms holds the reference's material?".
``MatchModel`` answers it with a Gaussian model of the descriptors (``core/texture.py``) of every
touch, reference touches included:

- Units: each descriptor dimension j is divided by the scene's spread s_j (std over the C + 1
  platforms' mean descriptors, plus a small floor), so no scale learned elsewhere is needed
  (``scene_units=False``: descriptors as given, e.g. whitened by a prepared representation).
- Platform p's touches are draws x ~ N(mu_p, diag(sigma^2)); sigma_j^2 is the pooled within-
  platform variance of this trial's repeated touches, shrunk toward ``prior_scale``^2 with the
  weight of ``prior_strength`` pseudo-observations: sigma_j^2 = (nu0 kappa^2 + SS_j) / (nu0 + dof).
- Hypothesis h: the reference platform shares mu with comparison h. With a flat prior on the
  means, the evidence for h is the predictive density of the reference mean r (k touches) given
  comparison h's mean x_h (n_h touches):
  l_h = -D/2 log v_h - 1/2 sum_j (r_j - x_hj)^2 / (sigma_j^2 v_h),  v_h = 1/k + 1/n_h.
- belief = softmax(``temperature`` * l): descriptor dimensions are correlated, so the raw
  likelihood is over-confident; the temperature is calibrated on real presses
  (``tactex experiment real``, docs/research/real_presses.md).

``separation`` (the "not sure" rule of the stop, ``core/engine.py``): how far apart the two
best comparisons' means are against what repeated touches of one platform give, t =
sum_j (x_a - x_b)_j^2 / (sigma_j^2 (1/n_a + 1/n_b)) / D; about 1 when a and b hold the same
material (the sampling spread of two means of n_a and n_b touches), growing with the touches
when they differ.

``info_gain`` scores every platform (0 = the reference, 1..C) by the expected drop of the
belief's entropy if it were touched once more (Monte Carlo over hypotheses and simulated
descriptors). ``samples`` gives (T, C) beliefs under posterior draws of the platform means, the
table the uncertainty strategies of ``core/strategies.py`` score.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

_EPS = 1e-12


def entropy(p: np.ndarray) -> float:
    """Entropy (nats) of a probability vector."""
    q = np.clip(np.asarray(p, dtype=np.float64), _EPS, 1.0)
    return float(-(q * np.log(q)).sum())


def softmax(logits: np.ndarray) -> np.ndarray:
    """Softmax over the last axis (float64)."""
    z = np.asarray(logits, dtype=np.float64)
    z = z - z.max(axis=-1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=-1, keepdims=True)


def separation(means: np.ndarray, counts: np.ndarray, sigma2: np.ndarray, a: int,
               b: int) -> float:
    """Distance of platform ``a``'s and ``b``'s means per dimension in units of its sampling
    spread (module docstring): ``means`` (P, D) and ``sigma2`` (D,) in one set of units,
    ``counts`` (P,) touches per platform. 1 = as far apart as two means of one material."""
    v = 1.0 / counts[a] + 1.0 / counts[b]
    d2 = float((((means[a] - means[b]) ** 2) / sigma2).sum())
    return d2 / (v * means.shape[1])


class MatchModel:
    """Descriptors of one trial's touches and the belief over the matching comparison."""

    def __init__(self, n_comparisons: int, prior_scale: float = 1.0,
                 prior_strength: float = 4.0, temperature: float = 0.05,
                 scale_floor: float = 0.05, scene_units: bool = True) -> None:
        if n_comparisons < 2:
            raise InputError(f"MatchModel needs >= 2 comparisons, got {n_comparisons}")
        for name, v in (("prior_scale", prior_scale), ("prior_strength", prior_strength),
                        ("temperature", temperature)):
            if not v > 0:
                raise InputError(f"MatchModel.{name} must be > 0, got {v}")
        self.C = n_comparisons
        self.kappa = float(prior_scale)
        self.nu0 = float(prior_strength)
        self.beta = float(temperature)
        self.floor = float(scale_floor)
        self.scene_units = bool(scene_units)
        self.samples_by_platform: list[list[np.ndarray]] = [[] for _ in range(self.C + 1)]

    # ------------------------------------------------------------------ data
    def add(self, platform: int, descriptor: np.ndarray) -> None:
        """Store the (D,) descriptor of a touch of ``platform`` (0 = reference, 1..C)."""
        if not 0 <= platform <= self.C:
            raise InputError(f"platform {platform} outside 0..{self.C}")
        x = np.asarray(descriptor, dtype=np.float64)
        if x.ndim != 1 or not np.all(np.isfinite(x)):
            raise InputError("descriptor must be a finite 1-D vector")
        if any(s and s[0].shape != x.shape for s in self.samples_by_platform):
            raise InputError(f"descriptor of size {x.size} differs from the stored ones")
        self.samples_by_platform[platform].append(x)

    @property
    def counts(self) -> np.ndarray:
        """(C + 1,) touches per platform, 0 = reference."""
        return np.array([len(s) for s in self.samples_by_platform])

    @property
    def ready(self) -> bool:
        return bool(np.all(self.counts > 0))

    def _check_ready(self) -> None:
        if not self.ready:
            missing = [p for p, n in enumerate(self.counts) if n == 0]
            raise InputError(f"belief needs a touch of every platform; missing {missing}")

    def stats(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(means (C+1, D), counts (C+1,), sigma^2 (D,)) in scene units."""
        means, counts, sigma2, _ = self._stats()
        return means, counts, sigma2

    def _stats(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``stats`` plus the (D,) scene scale that defines the units."""
        self._check_ready()
        means = np.stack([np.mean(s, axis=0) for s in self.samples_by_platform])
        if self.scene_units:
            spread = means.std(axis=0)
            scale = np.sqrt(spread ** 2 + (self.floor * (np.median(spread) + _EPS)) ** 2) + _EPS
        else:
            scale = np.ones(means.shape[1])
        ss = np.zeros(means.shape[1])
        dof = 0
        for s, m in zip(self.samples_by_platform, means, strict=True):
            if len(s) > 1:
                ss += (((np.stack(s) - m) / scale) ** 2).sum(axis=0)
                dof += len(s) - 1
        sigma2 = (self.nu0 * self.kappa ** 2 + ss) / (self.nu0 + dof)
        return means / scale, self.counts.astype(np.float64), sigma2, scale

    def comparison_proba(self, descriptor: np.ndarray) -> np.ndarray:
        """(C,) tempered nearest-mean probabilities of one more (unstored) comparison touch."""
        means, _, sigma2, scale = self._stats()
        d2 = (((np.asarray(descriptor) / scale - means[1:]) ** 2) / sigma2).sum(axis=1)
        return softmax(-0.5 * self.beta * d2)

    # ------------------------------------------------------------------ belief
    def _logits(self, means: np.ndarray, counts: np.ndarray, sigma2: np.ndarray) -> np.ndarray:
        """(..., C) tempered log evidence; ``means`` (..., C+1, D), ``counts`` (..., C+1)."""
        r = means[..., :1, :]
        x = means[..., 1:, :]
        v = 1.0 / counts[..., :1] + 1.0 / counts[..., 1:]              # (..., C)
        d2 = (((r - x) ** 2) / sigma2).sum(axis=-1)                     # (..., C)
        D = means.shape[-1]
        return self.beta * (-0.5 * D * np.log(v) - 0.5 * d2 / v)

    def log_evidence(self) -> np.ndarray:
        """(C,) untempered log evidence l of every hypothesis (belief = softmax(beta l))."""
        means, counts, sigma2 = self.stats()
        return self._logits(means, counts, sigma2) / self.beta

    def separation(self) -> float:
        """``separation`` of the two comparisons with the largest log evidence."""
        means, counts, sigma2 = self.stats()
        b, a = np.argsort(self._logits(means, counts, sigma2))[-2:] + 1
        return separation(means, counts, sigma2, int(a), int(b))

    def belief(self) -> np.ndarray:
        """(C,) probability that comparison c (index c-1) matches the reference."""
        means, counts, sigma2 = self.stats()
        return softmax(self._logits(means, counts, sigma2))

    def samples(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, C) beliefs under posterior draws of the platform means (epistemic spread)."""
        means, counts, sigma2 = self.stats()
        draws = means + rng.standard_normal((n,) + means.shape) * np.sqrt(
            sigma2 / counts[:, None])
        return softmax(self._logits(draws, np.broadcast_to(counts, (n,) + counts.shape),
                                    sigma2))

    def info_gain(self, rng: np.random.Generator, draws: int = 32) -> np.ndarray:
        """(C + 1,) expected entropy drop of the belief [nats] from one more touch of each
        platform (index 0 = the reference).

        For each platform: draw ``draws`` hypotheses h from the belief; under h, a new touch of
        the reference or of comparison h comes from their pooled mean, any other comparison's
        from its own mean, plus within-platform noise (predictive variance sigma^2 (1 + 1/n));
        the belief is recomputed with that descriptor added (sums updated in closed form,
        ``_one_more``).
        """
        means, counts, sigma2 = self.stats()
        b = softmax(self._logits(means, counts, sigma2))
        h0 = entropy(b)
        C, D = self.C, means.shape[1]
        hyp = rng.choice(C, size=draws, p=b) + 1                       # (M,) platform of h
        noise = rng.standard_normal((C + 1, draws, D))
        gains = np.zeros(C + 1)
        m0 = np.broadcast_to(means, (draws,) + means.shape)
        n0 = np.broadcast_to(counts, (draws,) + counts.shape)
        for a in range(C + 1):
            new_means, new_counts = _one_more(m0, n0, sigma2, a, hyp, noise[a])
            post = softmax(self._logits(new_means, new_counts, sigma2))
            gains[a] = h0 - float(np.mean([entropy(p) for p in post]))
        return gains

    def stop_chance(self, rng: np.random.Generator, theta: float, draws: int = 16,
                    inner: int = 8) -> np.ndarray:
        """(2, C + 1) the chance that the belief reaches ``theta`` within one (row 0) and
        within two (row 1) more touches, the first of platform a (column a, 0 = the
        reference), the second of the platform with the best one-touch chance from there.

        Simulated as ``info_gain`` simulates a touch (``_one_more``): ``draws`` hypotheses from
        the belief, one descriptor each (the same standard-normal draws for every platform:
        common random numbers); from each simulated state, ``inner`` hypotheses from that
        state's belief and one descriptor each per second platform. Row 0 is a multiple of
        1 / ``draws``, row 1 of 1 / (``draws`` ``inner``). The scale of the units and sigma^2
        stay those of now.
        """
        if draws < 1 or inner < 1:
            raise InputError(f"stop_chance: draws and inner must be >= 1, got {draws}, {inner}")
        means, counts, sigma2 = self.stats()
        b = softmax(self._logits(means, counts, sigma2))
        C, D = self.C, means.shape[1]
        hyp = rng.choice(C, size=draws, p=b) + 1
        noise = rng.standard_normal((draws, D))
        noise2 = rng.standard_normal((draws * inner, D))
        u = rng.random((draws, inner))
        m0 = np.broadcast_to(means, (draws,) + means.shape)
        n0 = np.broadcast_to(counts, (draws,) + counts.shape)
        out = np.zeros((2, C + 1))
        for a in range(C + 1):
            m1, n1 = _one_more(m0, n0, sigma2, a, hyp, noise)
            p1 = softmax(self._logits(m1, n1, sigma2))                       # (M, C)
            hit = p1.max(axis=-1) >= theta
            cdf = np.cumsum(p1, axis=-1)
            hyp2 = np.minimum((u[..., None] > cdf[:, None, :]).sum(-1), C - 1).ravel() + 1
            m2 = np.repeat(m1, inner, axis=0)
            n2 = np.repeat(n1, inner, axis=0)
            best = np.zeros(draws)
            for a2 in range(C + 1):
                mm, nn = _one_more(m2, n2, sigma2, a2, hyp2, noise2)
                hit2 = softmax(self._logits(mm, nn, sigma2)).max(axis=-1) >= theta
                best = np.maximum(best, hit2.reshape(draws, inner).mean(axis=1))
            out[0, a] = hit.mean()
            out[1, a] = np.where(hit, 1.0, best).mean()
        return out


def _one_more(means: np.ndarray, counts: np.ndarray, sigma2: np.ndarray, a: int,
              hyp: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per state m, one more simulated touch of platform ``a`` (0 = the reference): ``means``
    (M, C + 1, D) and ``counts`` (M, C + 1) in scene units, ``hyp`` (M,) the matching
    comparison (1..C) of each state, ``noise`` (M, D) standard normal. Under h the touch comes
    from the pooled mean of the reference and comparison h when ``a`` is either of them, else
    from ``a``'s own mean, with predictive variance sigma^2 (1 + 1/n) (n: the touches of that
    mean). Returns the new (means, counts), copies."""
    rows = np.arange(means.shape[0])
    c_h = counts[rows, hyp]
    if a == 0:
        pooled_n = counts[:, 0] + c_h
        mu = (means[:, 0] * counts[:, :1] + means[rows, hyp] * c_h[:, None]) / pooled_n[:, None]
    else:
        same = hyp == a
        both = counts[:, 0] + counts[:, a]
        pooled_n = np.where(same, both, counts[:, a])
        mu = np.where(same[:, None], (means[:, 0] * counts[:, :1] + means[:, a] *
                                      counts[:, a, None]) / both[:, None], means[:, a])
    x = mu + noise * np.sqrt(sigma2 * (1.0 + 1.0 / pooled_n[:, None]))
    new_means = np.array(means, dtype=np.float64)
    new_counts = np.array(counts, dtype=np.float64)
    new_means[:, a] = (means[:, a] * counts[:, a, None] + x) / (counts[:, a, None] + 1.0)
    new_counts[:, a] += 1.0
    return new_means, new_counts
