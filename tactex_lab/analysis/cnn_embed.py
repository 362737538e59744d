"""A small CNN embedding of a press trained on one library and screened on the other's classes
(issue 33, candidate d; lab only: torch on the CPU, nothing written but under /tmp).

Input: the contact difference (``texture.contact_difference``) of the strongest and the 3 extra
in-contact frames of each press, halved to (104, 144, 3) and divided by ``SCALE`` grey levels.
Network: 4 conv blocks (3x3 conv, batch norm, ReLU, 2x2 max pool; 8-16-32-32 channels),
global average pooling, a linear layer to ``EMBED`` numbers. Trained with a softmax over the
library's classes on 64 x 64 random crops under random 90-degree rotations and flips (the
texture's identity does not depend on where or at what angle it is pressed). A press's embedding:
the mean over its 4 frames, the 8 rotations / flips and 4 corner crops (the trial's rotation
invariance).
"""

from __future__ import annotations

import time

import numpy as np

SCALE = 8.0          # grey levels per input unit
CROP = 64            # px, training crop of the halved difference
EMBED = 32


def build_diffs(root: str) -> dict[str, np.ndarray]:
    """{'cls': (n,), 'x': (n, 4, 3, 104, 144) float16} for every press of the replay folder."""
    import cv2
    from tactex_ros.core import texture
    from tactex_ros.sources.replay import ReplaySource
    src = ReplaySource(root)
    cls, xs = [], []
    for c in src.classes:
        for path in src.presses(c):
            t = src.touch(path)
            four = [t.frame] + list(t.extra if t.extra is not None else [])
            four += [t.frame] * (4 - len(four))
            ds = [cv2.resize(texture.contact_difference(f, t.no_contact), (144, 104),
                             interpolation=cv2.INTER_AREA) for f in four[:4]]
            xs.append(np.stack(ds).transpose(0, 3, 1, 2) / SCALE)
            cls.append(c)
    return {"cls": np.array(cls), "x": np.stack(xs).astype(np.float16)}


def _net():
    import torch.nn as nn
    layers, cin = [], 3
    for cout in (8, 16, 32, 32):
        layers += [nn.Conv2d(cin, cout, 3, padding=1), nn.BatchNorm2d(cout), nn.ReLU(),
                   nn.MaxPool2d(2)]
        cin = cout
    return nn.Sequential(*layers, nn.AdaptiveAvgPool2d(1), nn.Flatten(), nn.Linear(cin, EMBED))


def _augment(x, rng: np.random.Generator):
    import torch
    n, _, h, w = x.shape
    i, j = rng.integers(0, h - CROP + 1), rng.integers(0, w - CROP + 1)
    x = x[:, :, i:i + CROP, j:j + CROP]
    x = torch.rot90(x, int(rng.integers(4)), (2, 3))
    return torch.flip(x, (3,)) if rng.random() < 0.5 else x


def train(lib: dict[str, np.ndarray], seconds: float = 150.0, seed: int = 0,
          batch: int = 32) -> tuple[object, dict]:
    """The network trained on the library ``lib`` (``build_diffs``) for ``seconds`` of CPU."""
    import torch
    import torch.nn as nn
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    classes = sorted(set(lib["cls"].tolist()))
    y = torch.tensor([classes.index(c) for c in lib["cls"]])
    x = torch.tensor(lib["x"].astype(np.float32))              # (n, 4, 3, H, W)
    net = _net()
    head = nn.Linear(EMBED, len(classes))
    opt = torch.optim.AdamW(list(net.parameters()) + list(head.parameters()), 2e-3,
                            weight_decay=1e-3)
    t0, step, losses = time.perf_counter(), 0, []
    net.train()
    while time.perf_counter() - t0 < seconds:
        rows = torch.tensor(rng.integers(0, len(y), batch))
        frames = torch.tensor(rng.integers(0, 4, batch))
        xb = _augment(x[rows, frames], rng)
        loss = nn.functional.cross_entropy(head(net(xb)), y[rows])
        opt.zero_grad()
        loss.backward()
        opt.step()
        step += 1
        if step % 50 == 0:
            losses.append(float(loss))
    return net, {"steps": step, "seconds": time.perf_counter() - t0, "loss": losses}


def embed(net, data: dict[str, np.ndarray]) -> np.ndarray:
    """(n, EMBED) mean embedding of every press (4 frames x 8 rotations / flips x 4 crops)."""
    import torch
    net.eval()
    x = torch.tensor(data["x"].astype(np.float32))
    n, f, c, h, w = x.shape
    out = np.zeros((n, EMBED))
    with torch.no_grad():
        for i, j in ((0, 0), (0, w - CROP), (h - CROP, 0), (h - CROP, w - CROP)):
            xc = x[:, :, :, i:i + CROP, j:j + CROP].reshape(n * f, c, CROP, CROP)
            for k in range(4):
                for flip in (False, True):
                    xr = torch.rot90(xc, k, (2, 3))
                    xr = torch.flip(xr, (3,)) if flip else xr
                    out += net(xr).reshape(n, f, EMBED).mean(1).numpy()
    return out / 32.0


def screen(a: dict[str, np.ndarray], b: dict[str, np.ndarray], diffs: dict[str, dict],
           seconds: float = 150.0, seeds: tuple[int, ...] = (0,),
           scenes: int = 3000) -> list[dict]:
    """Both directions: the network trained on the library's ``diffs`` (``build_diffs``, the
    presses in the caches' order), its embeddings scored with ``metric_screen.scene_hits``
    (no metric, and whitened on the library's embeddings) on the same scenes as
    ``metric_screen.feature_screen``, exact McNemar against the frame and the whitened frame."""
    from tactex_ros.core import representation
    from tactex_lab.analysis.metric_screen import scene_hits
    from tactex_lab.analysis.stats import mcnemar_exact
    import torch
    torch.set_num_threads(1)
    rows = []
    for name, tk, lk in (("a_with_b", "a", "b"), ("b_with_a", "b", "a")):
        test, lib = {"a": a, "b": b}[tk], {"a": a, "b": b}[lk]
        for k in (tk, lk):
            if not np.array_equal(diffs[k]["cls"], {"a": a, "b": b}[k]["cls"]):
                raise ValueError("press differences and cache list the presses differently")
        cls = test["cls"]
        libd = {c: lib["f0"][lib["cls"] == c] for c in sorted(set(lib["cls"].tolist()))}
        base = {"none": {p: scene_hits(test["f0"], cls, None, p, scenes) for p in (1, 2)}}
        white = representation.fit(libd, kind="whiten")
        base["whiten"] = {p: scene_hits(test["f0"], cls, white, p, scenes) for p in (1, 2)}
        for seed in seeds:
            net, log = train(diffs[lk], seconds, seed)
            zt, zl = embed(net, diffs[tk]), embed(net, diffs[lk])
            t0 = time.perf_counter()
            embed(net, {"x": diffs[tk]["x"][:8]})
            per_press_ms = (time.perf_counter() - t0) / 8 * 1e3
            zd = {c: zl[lib["cls"] == c] for c in sorted(set(lib["cls"].tolist()))}
            for kind in ("none", "whiten"):
                rep = None if kind == "none" else representation.fit(zd, kind="whiten")
                hits = {p: scene_hits(zt, cls, rep, p, scenes) for p in (1, 2)}
                rows.append({"direction": name, "feature": "cnn", "metric": kind, "seed": seed,
                             "train": {k: v for k, v in log.items() if k != "loss"},
                             "loss_first_last": log["loss"][:1] + log["loss"][-1:],
                             "embed_ms_per_press": per_press_ms,
                             "acc_1": float(hits[1].mean()), "acc_2": float(hits[2].mean()),
                             "vs_frame": {str(p): mcnemar_exact(hits[p], base["none"][p])
                                          for p in (1, 2)},
                             "vs_whiten": {str(p): mcnemar_exact(hits[p], base["whiten"][p])
                                           for p in (1, 2)}})
                r = rows[-1]
                print(f"{name} cnn seed {seed} {kind}: {r['acc_1']:.3f} / {r['acc_2']:.3f} "
                      f"p vs frame {r['vs_frame']['1']['p']:.2g} {r['vs_frame']['2']['p']:.2g} "
                      f"vs whiten {r['vs_whiten']['1']['p']:.2g} {r['vs_whiten']['2']['p']:.2g}"
                      f" ({log['steps']} steps)", flush=True)
    return rows
