"""The simulator's fabric tiles kept on disk between processes (sources.simulated.cached_tile)."""

from __future__ import annotations

import numpy as np

from tactex_ros.sim.fabrics import height_tile
from tactex_ros.sim.render import MM_PER_PX
from tactex_ros.sources import simulated
from tactex_ros.sources.simulated import TILE_PX, cached_tile, tile_file


def _fabric():
    from tactex_ros.core.paths import config_dir
    from tactex_ros.sim.fabrics import load_catalogue
    return load_catalogue(config_dir() / "fabrics.yaml")["satin"]


def test_a_tile_is_built_once_then_read_back_equal(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    fab = _fabric()
    path = tile_file(fab, 7)
    assert path.parent == tmp_path / "tactex" / "tiles" and not path.exists()
    cached_tile.cache_clear()
    built = cached_tile(fab, 7)
    assert path.is_file() and list(path.parent.iterdir()) == [path]   # no temporary left
    np.testing.assert_array_equal(built, height_tile(fab, TILE_PX, MM_PER_PX, 7))
    cached_tile.cache_clear()          # a new process: read from disk, not built
    monkeypatch.setattr(simulated, "height_tile", lambda *a: (_ for _ in ()).throw(
        AssertionError("built again")))
    np.testing.assert_array_equal(cached_tile(fab, 7), built)
    assert tile_file(fab, 8) != path and tile_file(fab, 7) == path
    cached_tile.cache_clear()


def test_a_damaged_tile_is_built_again_and_a_read_only_cache_still_gives_the_tile(
        tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    fab = _fabric()
    want = height_tile(fab, TILE_PX, MM_PER_PX, 3)
    path = tile_file(fab, 3)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"\x93NUMPY half a file")
    cached_tile.cache_clear()
    np.testing.assert_array_equal(cached_tile(fab, 3), want)
    np.testing.assert_array_equal(np.load(path), want)          # replaced by a whole one
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))           # nothing can be written
    cached_tile.cache_clear()
    np.testing.assert_array_equal(cached_tile(fab, 3), want)
    cached_tile.cache_clear()
