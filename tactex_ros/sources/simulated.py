"""Simulated touch source: every touch is a new random press of a procedural fabric.

Spec ``sim[:difficulty][:recorded]`` with difficulty ``easy`` (0.2), ``medium`` (0.5), ``hard``
(0.8) or a number in [0, 1]. Sessions: by default a trial is one recording session (a live
robot presses every platform with the same sensor state: one no-contact frame, the touches'
backgrounds equal). ``recorded`` simulates a recorded dataset replayed (``replay:DIR``): every
class was pressed in its own session, so its presses share a session background that the other
classes' lack (``GelSightRenderer.session_background``), and every press has its own no-contact
frame (``press_background``). Classes are the names of the fabric catalogue the source is given (the
package's is ``config/fabrics.yaml``: ``sources.open_source("sim")`` passes it). A scene drawn
at difficulty q (``draw_scene``) takes a random catalogue fabric as the base and places the
comparison fabrics around it at parameter distance (1 - q) * 0.6 from the base (Euclidean on the
normalised parameters, ``FabricParams.vector``), in different random directions, same family —
q = 1 makes them identical, q = 0 far apart; the reference is one of them.
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from collections.abc import Callable

import numpy as np

from ..core.errors import InputError
from ..core.touch import Touch
from ..core.paths import cache_dir
from ..sim.fabrics import FabricParams, height_tile, load_catalogue
from ..sim.render import MM_PER_PX, GelSightRenderer

DIFFICULTY = {"easy": 0.2, "medium": 0.5, "hard": 0.8}
TILE_PX = 768
SPREAD = 0.6


def parse_difficulty(text: str) -> float:
    """``easy|medium|hard|<number in [0, 1]>`` -> number."""
    if text in DIFFICULTY:
        return DIFFICULTY[text]
    try:
        q = float(text)
    except ValueError:
        raise InputError(f"sim difficulty {text!r}: use easy, medium, hard or a number "
                         "in [0, 1]") from None
    if not 0.0 <= q <= 1.0:
        raise InputError(f"sim difficulty {q} outside [0, 1]")
    return q


@lru_cache(maxsize=256)
def cached_tile(fab: FabricParams, seed: int) -> np.ndarray:
    """(TILE_PX, TILE_PX) float32 height tile [mm] of ``fab`` (``sim.fabrics.height_tile``),
    built once per process and kept on disk between processes (``tile_file``): building one
    takes 0.3-1 s of CPU, and every start of the simulated camera needs the scene's tiles."""
    path = tile_file(fab, seed)
    try:
        tile = np.load(path, allow_pickle=False)
        if tile.shape == (TILE_PX, TILE_PX) and tile.dtype == np.float32:
            return tile
    except (OSError, ValueError):
        pass                        # not built yet, or unreadable: build it again
    tile = height_tile(fab, TILE_PX, MM_PER_PX, seed)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npy")
        np.save(tmp, tile, allow_pickle=False)
        os.replace(tmp, path)       # whole or absent: a parallel reader never sees half
    except OSError:
        pass                        # a read-only or full cache only costs the next build
    return tile


def tile_file(fab: FabricParams, seed: int) -> Path:
    """The disk cache's file of ``cached_tile(fab, seed)`` under ``paths.cache_dir()``, named
    by a hash of everything the tile depends on: the fabric's parameters, the seed, the size and
    scale, the tile code (``sim/fabrics.py``'s bytes) and numpy's and OpenCV's versions."""
    import hashlib

    import cv2

    from ..sim import fabrics
    h = hashlib.sha256(repr((fab, seed, TILE_PX, MM_PER_PX, np.__version__,
                             cv2.__version__)).encode())
    h.update(Path(fabrics.__file__).read_bytes())
    return cache_dir() / "tiles" / f"{h.hexdigest()[:32]}.npy"


class SimSource:
    """Fabric simulator as a touch source (``sources.base.TouchSource``)."""

    def __init__(self, difficulty: str | float = "medium", *, catalogue: str | Path,
                 recorded: bool = False) -> None:
        """``catalogue``: the fabric catalogue file (YAML); ``difficulty``, ``recorded``: see
        the module."""
        self.difficulty = (parse_difficulty(difficulty) if isinstance(difficulty, str)
                           else float(difficulty))
        self.recorded = recorded
        self._sessions: dict[str, np.ndarray] = {}
        self.catalogue = load_catalogue(catalogue)
        self.fabrics: dict[str, FabricParams] = dict(self.catalogue)
        self.renderer = GelSightRenderer()

    @property
    def classes(self) -> list[str]:
        return list(self.catalogue)

    @property
    def known_classes(self) -> list[str]:
        """Catalogue fabrics and the fabrics drawn by ``draw_scene`` so far."""
        return list(self.fabrics)

    def no_contact(self, seed: int) -> np.ndarray:
        """The no-contact frame of the trial with ``seed`` (the one its touches carry)."""
        return self.renderer.no_contact(np.random.default_rng([seed, 37]))

    def by_number(self, number: int) -> str:
        """Catalogue name of fabric ``number`` (1-based, the catalogue's order)."""
        names = list(self.catalogue)
        if not 1 <= number <= len(names):
            raise InputError(f"fabric number {number} outside 1..{len(names)}")
        return names[number - 1]

    def fabric(self, name: str) -> FabricParams:
        if name not in self.fabrics:
            raise InputError(f"unknown fabric {name!r}; `tactex sim fabrics` lists them")
        return self.fabrics[name]

    def draw_scene(self, comparisons: int, seed: int) -> list[str]:
        """Comparison fabric names at this source's difficulty (new fabrics are registered)."""
        rng = np.random.default_rng([seed, 17])
        base_name = self.classes[int(rng.integers(len(self.classes)))]
        base = self.catalogue[base_name]
        radius = (1.0 - self.difficulty) * SPREAD
        v0 = base.vector()
        names = []
        for k in range(comparisons):
            d = rng.standard_normal(v0.size)
            d /= np.linalg.norm(d)
            fab = FabricParams.from_vector(base.family, v0 + radius * d)
            name = f"{base_name}~q{self.difficulty:g}s{seed}k{k}"
            self.fabrics[name] = fab
            names.append(name)
        return names

    def session(self, name: str) -> np.ndarray:
        """Background of the session in which class ``name`` was recorded (``recorded``
        mode; one per class, the same in every trial, as a recorded dataset's):
        (240, 320, 3) float32."""
        if name not in self._sessions:
            self.fabric(name)
            rng = np.random.default_rng([_stable_seed(name), 41])
            self._sessions[name] = self.renderer.session_background(rng)
        return self._sessions[name]

    def press_background(self, name: str, rng: np.random.Generator) -> np.ndarray | None:
        """No-contact background of one press of ``name``: in ``recorded`` mode its class's
        session varied per press, else None (the sensor's, the same for every press)."""
        if not self.recorded:
            return None
        return self.renderer.press_background(self.session(name), rng)

    def press(self, name: str, rng: np.random.Generator, depth_mm: float | None = None,
              background: np.ndarray | None = None) -> np.ndarray:
        """One random press of fabric ``name`` on ``background`` (``press_background``;
        None: the sensor's): uint8 RGB (240, 320, 3)."""
        fab = self.fabric(name)
        tile = cached_tile(fab, _stable_seed(name))
        heights = self.renderer.window(tile, rng)
        lo, hi = self.renderer.sensor.depth_mm
        d = rng.uniform(lo, hi) if depth_mm is None else depth_mm
        return self.renderer.render(heights, d, rng, softness=fab.softness,
                                    background=background)

    def trial(self, platform_classes: list[str], seed: int,
              depth_spread_mm: float | None = None) -> Callable[[int], Touch]:
        """Touch function of one trial (``TouchSource.trial``): every touch a new press of the
        platform's fabric; ``depth_spread_mm``: press depth uniform in the sensor's nominal
        depth +- this [mm] (clipped to 0.02..2 mm), the touches then carry no no-contact
        frame (the engine is given ``no_contact(seed)``)."""
        for c in set(platform_classes):
            self.fabric(c)
        rng = np.random.default_rng([seed, 23])
        if depth_spread_mm is not None:
            rng_d = np.random.default_rng([seed, 29])
            lo, hi = self.renderer.sensor.depth_mm
            mid = 0.5 * (lo + hi)

            def spread(platform: int) -> Touch:
                d = float(np.clip(mid + rng_d.uniform(-depth_spread_mm, depth_spread_mm),
                                  0.02, 2.0))
                name = platform_classes[platform]
                return Touch(frame=self.press(name, rng, depth_mm=d,
                                              background=self.press_background(name, rng)))

            return spread
        if self.recorded:
            def recorded(platform: int) -> Touch:
                # a recorded press: its own no-contact frame, in its class's session
                name = platform_classes[platform]
                bg = self.press_background(name, rng)
                return Touch(frame=self.press(name, rng, background=bg),
                             no_contact=self.renderer.no_contact(rng, background=bg))
            return recorded
        no_contact = self.no_contact(seed)

        def touch(platform: int) -> Touch:
            # the session's no-contact frame, as a real sensor records it before the trial
            return Touch(frame=self.press(platform_classes[platform], rng), no_contact=no_contact)

        return touch


def _stable_seed(name: str) -> int:
    """Seed of a fabric's height tile from its name (stable across processes)."""
    import zlib
    return zlib.crc32(name.encode())
