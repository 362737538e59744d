"""Issue 33's last two per-press candidates, screened class-disjoint in both directions with the
``--screen`` proxy (``metric_screen.scene_hits``) against today's default and the best prepared
feature (docs/research/unseen_materials.md, "Wavelet scattering and a small CNN"):

- **scattering** (kymatio's ``Scattering2D``, numpy frontend, J = 4, L = 8, second order) of the
  grey contact difference, spatially averaged and made rotation invariant: per scale the log
  mean first-order modulus over orientations and the moduli of its 2nd / 4th orientation
  harmonics; per scale pair (j1 < j2) and orientation gap |theta2 - theta1| (0 .. L/2) the log
  ratio of the second order to the first (how the fine scale's energy is modulated). Nothing
  trained; kymatio is a lab dependency, not the product's.
- **cnn**: a small CNN (4 convolutions, global average pooling, a 128-number embedding) trained
  with cross-entropy on the *library's* classes only (random 64 x 64 crops, flips and quarter
  turns of the half-resolution contact difference of each press's 4 in-contact frames), then
  the embedding of the test side's presses (whole half-resolution image, the strongest frame;
  ``cnn4`` averages the 4 frames). Trained on ``../shared`` in the lab only: never shipped.

The contact differences are computed once per library into an image cache (.npz under /tmp:
``../shared`` data, never into the repository).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tactex_ros.core import texture
from tactex_ros.core.errors import InputError

SCAT_J = 4          # the better of J = 3 and 4 in the screen
SCAT_L = 8
HALF = 2            # the CNN's images: the contact difference subsampled by 2 (area)
CROP = 64           # px of the half-resolution image per training crop
EMBED = 128
SIM_VARIANTS = 150  # the simulator's training fabrics beside its 25 catalogue ones
SIM_PER_CLASS = 8


#: Cache arrays that depend on the direction: ``<k>`` is the press embedded by the network
#: trained on the *other* library (the test side's view), ``<k>_lib`` by the one trained on its
#: own (the library's view: the metric is fitted on what that network makes of the library).
LEARNED = ("cnn", "cnn4")


def library_view(cache: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The cache as the library side of a direction sees it: every ``LEARNED`` array replaced
    by its ``_lib`` twin (a cache without learned arrays is returned as is)."""
    return {**cache, **{k: cache[f"{k}_lib"] for k in LEARNED if f"{k}_lib" in cache}}


def touch_stack(touches) -> tuple[np.ndarray, np.ndarray]:
    """For every touch of the iterable ``touches``: the full-resolution grey contact difference
    of the strongest frame ((n, 208, 288) float32) and the half-resolution colour differences
    of its 4 in-contact frames ((n, 4, 3, 104, 144) float16; a touch with fewer frames repeats
    the strongest)."""
    import cv2
    grey, half = [], []
    for touch in touches:
        frames = [touch.frame] + list(touch.extra if touch.extra is not None else [])
        frames += [touch.frame] * (4 - len(frames))
        ds = [texture.contact_difference(f, touch.no_contact) for f in frames[:4]]
        grey.append(ds[0].mean(axis=2))
        half.append(np.stack([cv2.resize(d, (d.shape[1] // HALF, d.shape[0] // HALF),
                                         interpolation=cv2.INTER_AREA).transpose(2, 0, 1)
                              for d in ds]).astype(np.float16))
    return np.stack(grey).astype(np.float32), np.stack(half)


def contact_stack(root: str | Path, paths: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """``touch_stack`` of the press files ``paths`` (in that order) of the replay folder
    ``root``."""
    from tactex_ros.sources.replay import ReplaySource
    src = ReplaySource(root)
    return touch_stack(src.touch(Path(p)) for p in paths)


def sim_family(cache_dir: str | Path, per_class: int = 6, seed: int = 0) -> dict[str, np.ndarray]:
    """The simulator's catalogue fabrics as a third family (``experiment families``' ``sim``:
    ``per_class`` presses of each fabric in one live session): ``cls``, the 129-number
    descriptors ``f0`` (106) and ``hm`` (23) of each press, and its images (``touch_stack``:
    ``grey``, ``half``), cached as ``sim_<per_class>_s<seed>_stack.npz`` under ``cache_dir``."""
    path = Path(cache_dir) / f"sim_{per_class}_s{seed}_stack.npz"
    if not path.is_file():
        from tactex_ros import sources
        from tactex_ros.core.config import preset
        from tactex_ros.core.descriptor import raw_descriptor
        src = sources.open_source("sim")
        names = src.classes
        touch = src.trial(names, seed)
        touches = [(n, touch(i)) for i, n in enumerate(names) for _ in range(per_class)]
        cfg = preset("descriptor", descriptor_height_map=True)
        desc = np.stack([raw_descriptor(t, cfg) for _, t in touches])
        grey, half = touch_stack(t for _, t in touches)
        np.savez(path, cls=np.array([n for n, _ in touches]), f0=desc[:, :texture.DIM],
                 hm=desc[:, texture.DIM:], grey=grey, half=half)
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def sim_training_set(cache_dir: str | Path, variants: int = 150, per_class: int = 8,
                     seed: int = 0) -> dict[str, np.ndarray]:
    """Presses of simulated fabrics to train a network the product may ship (nothing of
    ``../shared``): the 25 catalogue fabrics and ``variants`` more, each drawn around a random
    catalogue fabric as ``draw_scene`` draws a scene's comparisons at difficulty 0 (the widest
    spread), ``per_class`` presses of each in the recorded mode (every fabric its own session
    background, every press its own no-contact frame). Returns ``cls`` (n,) and ``half``
    (n, 1, 3, 104, 144) float16 half-resolution contact differences (``touch_stack``'s), cached
    as ``simtrain_v<variants>_p<per_class>_s<seed>.npz`` under ``cache_dir``."""
    path = Path(cache_dir) / f"simtrain_v{variants}_p{per_class}_s{seed}.npz"
    if not path.is_file():
        from tactex_ros import sources
        src = sources.open_source("sim:0:recorded")
        names = list(src.classes)
        for v in range(variants):
            names += src.draw_scene(1, 100_000 * seed + v)
        touch = src.trial(names, seed)
        cls = [n for n in names for _ in range(per_class)]
        _, half = touch_stack(touch(i) for i, n in enumerate(names) for _ in range(per_class))
        np.savez(path, cls=np.array(cls), half=half[:, :1])
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


class Scattering:
    """Rotation-invariant averaged scattering of a (H, W) grey image -> (dim,) float."""

    def __init__(self, shape: tuple[int, int], j: int = SCAT_J, ell: int = SCAT_L) -> None:
        try:
            # kymatio.numpy also imports its 3-D part, which needs scipy.special.sph_harm
            # (gone in scipy 1.15): the 2-D frontend alone
            from kymatio.scattering2d.frontend.numpy_frontend import (
                ScatteringNumPy2D as Scattering2D)
        except ImportError as exc:   # the lab's requirements hold kymatio
            raise InputError("the scattering screen needs kymatio (requirements-lab.txt)") from exc
        self.j, self.ell = j, ell
        self.op = Scattering2D(J=j, shape=shape, L=ell, max_order=2, out_type="list")
        self.dim = 3 * j + j * (j - 1) // 2 * (ell // 2 + 1)

    def __call__(self, img: np.ndarray) -> np.ndarray:
        """(H, W) float32 -> (dim,) log features (``dim`` = 3 J + J(J-1)/2 (L/2 + 1); the
        zeroth order, the image's mean, is left out: the difference's mean is removed)."""
        coefs = self.op(np.ascontiguousarray(img, dtype=np.float32))
        j, ell = self.j, self.ell
        s1 = np.zeros((j, ell))
        s2 = np.zeros((j, j, ell // 2 + 1))
        n2 = np.zeros_like(s2)
        for c in coefs:
            m = float(np.mean(c["coef"]))
            if len(c["j"]) == 0:
                continue
            if len(c["j"]) == 1:
                s1[c["j"][0], c["theta"][0]] = m
            else:
                (j1, j2), (t1, t2) = c["j"], c["theta"]
                gap = abs(t2 - t1) % ell
                gap = min(gap, ell - gap)
                s2[j1, j2, gap] += m
                n2[j1, j2, gap] += 1
        first = s1.mean(axis=1)
        harm = np.abs(np.fft.rfft(s1, axis=1))[:, [1, 2]] / (s1.sum(axis=1, keepdims=True) + 1e-9)
        pairs = [np.log(s2[a, b] / np.maximum(n2[a, b], 1) + 1e-6) - np.log(first[a] + 1e-6)
                 for a in range(j) for b in range(a + 1, j)]
        return np.concatenate([np.log(first + 1e-6), harm.ravel()] + pairs)


def scattering_features(grey: np.ndarray) -> tuple[np.ndarray, float]:
    """(n, H, W) grey differences -> ((n, dim) features, median ms per press)."""
    op = Scattering(grey.shape[1:])
    rows, ms = [], []
    for g in grey:
        t0 = time.perf_counter()
        rows.append(op(g))
        ms.append(1e3 * (time.perf_counter() - t0))
    return np.stack(rows), float(np.median(ms))


def _net(classes: int):
    import torch.nn as nn

    def block(i: int, o: int, k: int, s: int) -> list:
        return [nn.Conv2d(i, o, k, s, k // 2, bias=False), nn.BatchNorm2d(o), nn.ReLU(True)]
    body = nn.Sequential(*block(3, 32, 5, 2), *block(32, 64, 3, 2), *block(64, 96, 3, 2),
                         *block(96, EMBED, 3, 1), nn.AdaptiveAvgPool2d(1), nn.Flatten())
    return body, nn.Sequential(nn.Dropout(0.2), nn.Linear(EMBED, classes))


def _normalise(x: np.ndarray, norm: str, scale: float) -> np.ndarray:
    """(..., 3, h, w) differences as the network sees them: divided by ``scale`` (``norm``
    "global": the training set's standard deviation) or by each frame's own standard
    deviation ("image": the press's contrast left out, as a simulator's differs from a
    sensor's)."""
    x = x.astype(np.float32)
    if norm == "global":
        return x / scale
    if norm == "image":
        return x / (x.std(axis=(-3, -2, -1), keepdims=True) + 1e-6)
    raise InputError(f"norm {norm!r}: use global or image")


AUGS = ("geometric", "photometric")


def _photometric(xb, rng: np.random.Generator):
    """The sensor's look varied per crop ((B, 3, h, w) scaled differences, in place of a new
    tensor): contrast x 0.5-2 (log-uniform), each channel's gain x exp(N(0, 0.15)), a 3 x 3 blur
    for half of the crops, Gaussian noise of 0-0.15 standard deviations: a real gel's contrast,
    LEDs, focus and noise differ from the simulator's."""
    import torch
    import torch.nn.functional as F
    b = xb.shape[0]
    gain = np.exp(rng.uniform(np.log(0.5), np.log(2.0), (b, 1, 1, 1))
                  + rng.normal(0.0, 0.15, (b, 3, 1, 1)))
    xb = xb * torch.from_numpy(gain.astype(np.float32))
    blur = torch.from_numpy(rng.random(b) < 0.5)
    if bool(blur.any()):
        xb = torch.where(blur[:, None, None, None], F.avg_pool2d(xb, 3, 1, 1,
                                                                 count_include_pad=False), xb)
    sigma = torch.from_numpy(rng.uniform(0.0, 0.15, (b, 1, 1, 1)).astype(np.float32))
    noise = torch.from_numpy(rng.standard_normal(xb.shape).astype(np.float32))
    return xb + sigma * noise


def train_cnn(half: np.ndarray, cls: np.ndarray, steps: int = 800, batch: int = 32,
              seed: int = 0, threads: int = 1, norm: str = "global",
              aug: str = "geometric") -> tuple[object, dict]:
    """Train the embedding on a library ((n, frames, 3, h, w) half-resolution differences,
    (n,) class names): cross-entropy over the library's classes, AdamW, cosine schedule; each
    crop turned and mirrored (``aug`` "geometric"), and its look varied too ("photometric":
    ``_photometric``). Returns (the embedding network in eval mode, {steps, seconds, final
    loss, scale, norm, aug})."""
    import torch
    import torch.nn.functional as F
    if aug not in AUGS:
        raise InputError(f"aug {aug!r}: use one of {', '.join(AUGS)}")
    torch.manual_seed(seed)
    torch.set_num_threads(threads)
    rng = np.random.default_rng(seed)
    names = sorted(set(cls.tolist()))
    y = np.array([names.index(c) for c in cls])
    scale = float(np.std(half.astype(np.float32))) + 1e-6
    x = torch.from_numpy(_normalise(half, norm, scale))          # (n, frames, 3, h, w)
    body, head = _net(len(names))
    opt = torch.optim.AdamW(list(body.parameters()) + list(head.parameters()), 2e-3,
                            weight_decay=1e-3)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps)
    h, w = x.shape[-2:]
    t0, loss = time.perf_counter(), None
    body.train(), head.train()
    for _ in range(steps):
        i = rng.integers(len(y), size=batch)
        f = rng.integers(x.shape[1], size=batch)
        r, c = rng.integers(h - CROP + 1, size=batch), rng.integers(w - CROP + 1, size=batch)
        xb = torch.stack([x[a, b, :, rr:rr + CROP, cc:cc + CROP]
                          for a, b, rr, cc in zip(i, f, r, c, strict=True)])
        k = int(rng.integers(4))
        xb = torch.rot90(xb, k, (2, 3))
        if rng.random() < 0.5:
            xb = torch.flip(xb, (3,))
        if aug == "photometric":
            xb = _photometric(xb, rng)
        out = head(body(xb))
        loss = F.cross_entropy(out, torch.from_numpy(y[i]), label_smoothing=0.1)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    body.eval()
    return body, {"steps": steps, "seconds": time.perf_counter() - t0,
                  "loss": float(loss.detach()), "scale": scale, "norm": norm, "aug": aug}


def embed(body, half: np.ndarray, scale: float,
          norm: str = "global") -> tuple[np.ndarray, np.ndarray, float]:
    """Embeddings of (n, 4, 3, h, w) presses: the strongest frame's (n, EMBED), the mean over
    the 4 frames (n, EMBED), and the median ms per press (4 frames, one thread); ``scale``,
    ``norm``: the training's (``train_cnn``'s log)."""
    import torch
    one, four, ms = [], [], []
    with torch.no_grad():
        for p in half:
            t0 = time.perf_counter()
            e = body(torch.from_numpy(_normalise(p, norm, scale))).numpy()
            ms.append(1e3 * (time.perf_counter() - t0))
            one.append(e[0])
            four.append(e.mean(0))
    return np.stack(one), np.stack(four), float(np.median(ms))


STRIDES = (2, 2, 2, 1)   # _net's convolutions


def to_embedding(body, log: dict, trained_on: dict):
    """The trained embedding network (``train_cnn``: the network and its log) as the product's
    numpy ``core.embedding.Embedding`` (batch normalisation folded in)."""
    from tactex_ros.core import embedding
    state = {k: v.detach().numpy() for k, v in body.state_dict().items()
             if not k.endswith("num_batches_tracked")}
    return embedding.from_torch(state, STRIDES, log["scale"], log.get("norm", "global"),
                                trained_on)


def _keys(path: Path) -> list[str]:
    with np.load(path, allow_pickle=False) as z:
        return list(z.files)


def _embed_sides(out: dict, body, log: dict, stacks: dict, roots: dict[str, str],
                 norm: str) -> float:
    """Embed both libraries' presses with the trained ``body`` into ``out``
    (``<library>_one`` / ``<library>_four``, ``embed``'s); returns the median ms per press."""
    ms = float("nan")
    for side, side_root in roots.items():
        name = Path(side_root).name
        out[f"{name}_one"], out[f"{name}_four"], ms = embed(body, stacks[side]["half"],
                                                            log["scale"], norm)
    return ms


def _add_shipped(caches: dict[str, dict[str, np.ndarray]], roots: dict[str, str],
                 d: Path) -> None:
    """``cnn`` / ``cnn4`` (and their library views) of every press as the product embeds it:
    the shipped network (``core.embedding``, ``descriptor_embedding`` "sim") on the strongest
    frame and on up to 4 in-contact frames (``embed_touch``), cached per network identity.
    Two passes on purpose: the first row of a 4-frame batch differs from the 1-frame call by
    up to 5e-7 (float32 rounding), and the cache equals the product's own numbers bit for bit."""
    from tactex_ros.core import embedding
    from tactex_ros.sources.replay import ReplaySource
    emb = embedding.load(embedding.resolve("sim"))
    for k, root in roots.items():
        path = d / f"cnn_shipped_{emb.identity}_{Path(root).name}.npz"
        if not path.is_file():
            src = ReplaySource(root)
            touches = [src.touch(Path(p)) for p in caches[k]["path"]]
            np.savez(path, one=np.stack([embedding.embed_touch(t, 1, emb) for t in touches]),
                     four=np.stack([embedding.embed_touch(t, 4, emb) for t in touches]))
        with np.load(path) as z:
            caches[k].update(cnn=z["one"], cnn4=z["four"], cnn_lib=z["one"], cnn4_lib=z["four"])


def add_to_caches(caches: dict[str, dict[str, np.ndarray]], roots: dict[str, str],
                  cache_dir: str | Path, scattering: bool = False, cnn_seed: int | None = None,
                  cnn_steps: int = 800, sim: dict[str, np.ndarray] | None = None,
                  cnn_train: str = "other", cnn_norm: str = "global",
                  cnn_variants: int = SIM_VARIANTS, cnn_aug: str = "geometric") -> None:
    """Add the learned candidates to ``experiment unseen``'s two caches ({"a", "b"}: press
    caches of the replay folders ``roots``), in place: ``scat`` (the scattering of each press)
    with ``scattering``; with ``cnn_seed``, a network trained on each library and ``cnn`` /
    ``cnn4`` = the press embedded by the *other* library's network (the test view), ``cnn_lib``
    / ``cnn4_lib`` by its own (``press_cache.library_view``). Images, scattering and embeddings
    are cached under ``cache_dir`` (``../shared`` data: /tmp, never the repository). ``sim``
    (``sim_family``): each library's network also embeds the simulator's fabrics, kept as
    ``caches[k]["sim"]``, a press cache of that family as library k's network sees it (one
    frame per press: its 4-frame features repeat it). ``cnn_train`` "sim": one network trained
    on the simulator's fabrics (``sim_training_set``) embeds both libraries, so the test and the
    library view are the same, and its weights are kept in the cache file (``net/...``);
    ``cnn_norm``, ``cnn_aug``: ``train_cnn``'s ``norm`` and ``aug``; ``cnn_variants``: the sim
    training set's ``variants``. ``cnn_train`` "shipped": no training, the product's shipped
    network embeds both libraries (``_add_shipped``; no ``cnn_seed`` needed)."""
    d = Path(cache_dir)
    stacks = {}
    for k, root in roots.items():
        path = d / f"{Path(root).name}_stack.npz"
        if not path.is_file():
            grey, half = contact_stack(root, [str(p) for p in caches[k]["path"]])
            np.savez(path, grey=grey, half=half, path=caches[k]["path"])
        with np.load(path, allow_pickle=False) as z:
            if not np.array_equal(z["path"], caches[k]["path"]):
                raise InputError(f"{path}: its presses are not the cache's (delete it)")
            stacks[k] = {"grey": z["grey"], "half": z["half"]}
    if scattering:
        for k, root in roots.items():
            path = d / f"{Path(root).name}_scat_j{SCAT_J}.npz"
            if not path.is_file():
                x, ms = scattering_features(stacks[k]["grey"])
                np.savez(path, scat=x, ms=np.array(ms))
                print(f"scattering of {root}: {x.shape[1]} numbers, median {ms:.0f} ms per press",
                      flush=True)
            with np.load(path) as z:
                caches[k]["scat"] = z["scat"]
    if cnn_train == "shipped":
        _add_shipped(caches, roots, d)
        return
    if cnn_seed is None:
        return
    if cnn_train not in ("other", "sim"):
        raise InputError(f"cnn_train {cnn_train!r}: use other, sim or shipped")
    tag = ("" if cnn_norm == "global" else f"_{cnn_norm}") + (
        "" if cnn_aug == "geometric" else f"_{cnn_aug}")
    if cnn_train == "sim":
        path = d / f"cnn_sim_v{cnn_variants}_s{cnn_seed}_n{cnn_steps}{tag}.npz"
        if not path.is_file():
            train = sim_training_set(d, variants=cnn_variants, per_class=SIM_PER_CLASS)
            body, log = train_cnn(train["half"], train["cls"], steps=cnn_steps, seed=cnn_seed,
                                  norm=cnn_norm, aug=cnn_aug)
            out = {f"net/{k}": v.numpy() for k, v in body.state_dict().items()}
            ms = _embed_sides(out, body, log, stacks, roots, cnn_norm)
            np.savez(path, **out, log=np.array(str(dict(log, embed_ms=ms))))
            print(f"cnn trained on the simulator's fabrics: {log}, embedding {ms:.1f} ms per "
                  "press", flush=True)
        with np.load(path) as z:
            for k, root in roots.items():
                name = Path(root).name
                caches[k].update(cnn=z[f"{name}_one"], cnn4=z[f"{name}_four"],
                                 cnn_lib=z[f"{name}_one"], cnn4_lib=z[f"{name}_four"])
        return
    emb: dict[str, dict[str, np.ndarray]] = {}   # net trained on k -> {press side: embeddings}
    for k, root in roots.items():
        path = d / f"cnn_{Path(root).name}_s{cnn_seed}_n{cnn_steps}{tag}.npz"
        if not path.is_file() or (sim is not None and "sim_one" not in _keys(path)):
            body, log = train_cnn(stacks[k]["half"], caches[k]["cls"], steps=cnn_steps,
                                  seed=cnn_seed, norm=cnn_norm, aug=cnn_aug)
            out = {}
            ms = _embed_sides(out, body, log, stacks, roots, cnn_norm)
            if sim is not None:
                out["sim_one"], out["sim_four"], _ = embed(body, sim["half"], log["scale"],
                                                           cnn_norm)
            np.savez(path, **out, log=np.array(str(dict(log, embed_ms=ms))))
            print(f"cnn trained on {root}: {log}, embedding {ms:.1f} ms per press", flush=True)
        with np.load(path) as z:
            emb[k] = {key: z[key] for key in z.files if key != "log"}
    for k, root in roots.items():
        other, name = ("b" if k == "a" else "a"), Path(root).name
        caches[k].update(cnn=emb[other][f"{name}_one"], cnn4=emb[other][f"{name}_four"],
                         cnn_lib=emb[k][f"{name}_one"], cnn4_lib=emb[k][f"{name}_four"])
        if sim is not None:       # the sim family as this library's network embeds it
            caches[k]["sim"] = {"cls": sim["cls"], "f0": sim["f0"], "hm": sim["hm"],
                                "extra": np.repeat(sim["f0"][:, None], 3, axis=1),
                                "cnn": emb[k]["sim_one"], "cnn4": emb[k]["sim_four"]}
