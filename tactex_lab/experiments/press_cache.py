"""Recorded presses described once (a cache, .npz) and given back as the touches of a trial:
the per-press features of ``tactex experiment unseen`` and ``ladder`` (docs/research/unseen_materials.md).

The cache holds descriptors of ``../shared`` presses: write it under /tmp, never into the
repository.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tactex_ros.core import calibration as belief_calibration
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch


def _frames4(c: dict[str, np.ndarray]) -> np.ndarray:
    """(n, DIM) the descriptor averaged over the strongest frame and the 3 extra frames."""
    return np.mean(np.concatenate([c["f0"][:, None], c["extra"]], axis=1), 1)


#: Per-press features: cache arrays -> (n, D') vectors.
FEATURES = {
    "frame": lambda c: c["f0"],
    "frames4": _frames4,
    "growth": lambda c: np.concatenate([c["f0"], c["early"] - c["f0"]], axis=1),
    "regions": lambda c: np.concatenate([c["reg"].mean(1), c["reg"].std(1)], axis=1),
    "frame_regstd": lambda c: np.concatenate([c["f0"], c["reg"].std(1)], axis=1),
    # issue 33 candidates (analysis/press_features.py)
    "fb": lambda c: c["fb"],
    "hm": lambda c: c["hm"],
    "fb_hm": lambda c: np.concatenate([c["fb"], c["hm"]], axis=1),
    "frame_fb": lambda c: np.concatenate([c["f0"], c["fb"]], axis=1),
    "frame_hm": lambda c: np.concatenate([c["f0"], c["hm"]], axis=1),
    "frame_grow": lambda c: np.concatenate([c["f0"], c["grow"]], axis=1),
    "frames4_fb": lambda c: np.concatenate([_frames4(c), c["fb"]], axis=1),
    "frames4_hm": lambda c: np.concatenate([_frames4(c), c["hm"]], axis=1),
    "frames4_grow": lambda c: np.concatenate([_frames4(c), c["grow"]], axis=1),
    "frames4_all": lambda c: np.concatenate([_frames4(c), c["fb"], c["hm"], c["grow"]], axis=1),
    # issue 33's last candidates (analysis/learned_features.py; --scattering, --cnn-seed)
    "scat": lambda c: c["scat"],
    "frame_hm_scat": lambda c: np.concatenate([c["f0"], c["hm"], c["scat"]], axis=1),
    "cnn": lambda c: c["cnn"],
    "cnn4": lambda c: c["cnn4"],
    "frame_hm_cnn": lambda c: np.concatenate([c["f0"], c["hm"], c["cnn"]], axis=1),
    "frames4_hm_cnn4": lambda c: np.concatenate([_frames4(c), c["hm"], c["cnn4"]], axis=1),
    # the strongest frame described, the embedding averaged over 4 (the cheap multi-frame one)
    "frame_hm_cnn4": lambda c: np.concatenate([c["f0"], c["hm"], c["cnn4"]], axis=1),
}

def build_cache(root: str | Path, out: str | Path, candidates: bool = False) -> Path:
    """Describe every press of the replay folder ``root`` once: the strongest frame (``f0``),
    the 3 other in-contact frames of the touch (``extra``); then either the first frame with
    half the strongest contact score (``early``) and the 2 x 2 regions of the strongest frame's
    contact difference (``reg``), or with ``candidates`` issue 33's candidates
    (``analysis/press_features.py``): the filter bank (``fb``) and the height map (``hm``) of
    the strongest frame and the contact's growth (``grow``). With the class and file of each
    press. Written as ``out`` (.npz)."""
    from tactex_ros.core import texture
    from tactex_ros.core.contact import strongest_contact
    from tactex_ros.sources.replay import ReplaySource, read_video
    from tactex_lab.analysis import press_features as pf
    src = ReplaySource(root)
    keys = ("fb", "hm", "grow") if candidates else ("early", "reg")
    rows: dict[str, list] = {k: [] for k in ("cls", "path", "f0", "extra") + keys}
    for cls in src.classes:
        for path in src.presses(cls):
            arr = read_video(path)
            touch = src.touch(path)
            nc = touch.no_contact
            idx, scores = strongest_contact(arr)
            f0 = texture.describe(touch.frame, nc)
            ex = [texture.describe(x, nc) for x in (touch.extra if touch.extra is not None
                                                    else [])]
            ex += [f0] * (3 - len(ex))
            d = texture.contact_difference(touch.frame, nc)
            row = {"cls": cls, "path": str(path), "f0": f0, "extra": np.stack(ex[:3])}
            if candidates:
                row.update(fb=pf.filter_bank(d), hm=pf.height_map(d),
                           grow=pf.growth(arr[..., ::-1], nc, scores, idx))
            else:
                rise = np.flatnonzero(scores[:idx + 1] >= 0.5 * scores[idx])
                row["early"] = texture.describe(
                    np.ascontiguousarray(arr[rise[0] if len(rise) else idx, ..., ::-1]), nc)
                h, w = d.shape[0] // 2, d.shape[1] // 2
                row["reg"] = np.stack([texture.describe_difference(
                    d[i * h:(i + 1) * h, j * w:(j + 1) * w]) for i in range(2) for j in range(2)])
            for k, v in row.items():
                rows[k].append(v)
    out = Path(out)
    np.savez(out, **{k: np.array(v) for k, v in rows.items()})
    return out


def load_cache(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays ``build_cache`` wrote."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"feature cache not found: {p} (build it with --build-cache)")
    with np.load(p, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def cached(root: str | Path, cache_dir: str | Path, candidates: bool = False,
           rebuild: bool = False) -> dict[str, np.ndarray]:
    """The presses of the replay folder ``root`` as ``load_cache`` returns them, from
    ``<cache_dir>/<folder>[_candidates].npz``; built first (``build_cache``) when the file is
    missing or ``rebuild``. The one cache naming every experiment shares."""
    path = Path(cache_dir) / f"{Path(root).name}{'_candidates' * candidates}.npz"
    if rebuild or not path.is_file():
        print(f"describing every press of {root} -> {path}", flush=True)
        build_cache(root, path, candidates=candidates)
    return load_cache(path)


def add_contact_verdicts(cache: dict[str, np.ndarray], root: str | Path,
                         cache_dir: str | Path) -> None:
    """``cache["contact_ok"]`` (n,) bool: the product's contact guard on each press, against
    its own no-contact frame (``core.guards.press_verdict`` at the shipped learner's
    ``contact_flat_min`` / ``contact_min``), as a trial on the robot judges it. Kept in
    ``<cache_dir>/<folder>_contact.npz`` beside the feature cache (checked against its paths)."""
    from tactex_ros.core.config import preset
    from tactex_ros.core.guards import press_verdict
    from tactex_ros.sources.replay import ReplaySource
    cfg = preset("default")
    path = Path(cache_dir) / f"{Path(root).name}_contact.npz"
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            if (z["path"].shape == cache["path"].shape and (z["path"] == cache["path"]).all()
                    and float(z["contact_min"]) == cfg.contact_min
                    and float(z["flat_min"]) == cfg.contact_flat_min):
                cache["contact_ok"] = z["ok"]
                return
    src = ReplaySource(root)
    ok = np.array([press_verdict(src.touch(Path(p)), cfg.contact_flat_min, cfg.contact_min)[0]
                   for p in cache["path"]])
    np.savez(path, path=cache["path"], ok=ok, contact_min=cfg.contact_min,
             flat_min=cfg.contact_flat_min)
    cache["contact_ok"] = ok


def by_class(cache: dict[str, np.ndarray], feature: str) -> dict[str, np.ndarray]:
    """{class: (n_c, D') feature vectors} (of a library: pass ``library_view(cache)``); with
    ``contact_ok`` in the cache (``add_contact_verdicts``) only the presses the guard accepts."""
    x = FEATURES[feature](cache)
    keep = cache.get("contact_ok", np.ones(len(x), bool))
    return {c: x[(cache["cls"] == c) & keep] for c in sorted(set(cache["cls"].tolist()))}


class CachedPresses:
    """A ReplaySource look-alike whose touches carry their cached feature vector; a press
    marked ``rejected`` ((n,) bool, e.g. ``~contact_ok``) fails when touched, as a press the
    contact guard refuses on the robot: the engine records it and presses again (its retries
    draw another press of the class)."""

    one_session = False

    def __init__(self, x: np.ndarray, cls: np.ndarray, rejected: np.ndarray | None = None
                 ) -> None:
        self.x = x
        self.rejected = np.zeros(len(x), bool) if rejected is None else np.asarray(rejected)
        self.rows = {c: list(np.flatnonzero(cls == c)) for c in set(cls.tolist())}

    def check_class(self, c: str) -> None:
        if c not in self.rows:
            raise InputError(f"class {c!r} not in the cache")

    def presses(self, c: str) -> list[int]:
        return self.rows[c]

    def touch(self, row: int) -> Touch:
        if self.rejected[row]:
            from tactex_ros.core.engine import TouchFailed
            raise TouchFailed(f"cached press {row}: no contact (the contact guard)")
        return Touch(belief_calibration.PLACEHOLDER_FRAME, None, None, self.x[row])
