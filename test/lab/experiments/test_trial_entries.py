"""Trial files name classes by number: ``experiments.trials.class_name`` maps an entry through
the source's numbering and names a bad entry."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_lab.experiments.trials import class_name
from tactex_ros.core.errors import InputError
from tactex_ros.sources import open_source


def test_class_numbers_of_both_sources(tmp_path: Path):
    rng = np.random.default_rng(0)
    for cls in ("a", "b", "c"):
        (tmp_path / cls).mkdir()
        for k in range(2):
            cv2.imwrite(str(tmp_path / cls / f"{k}.png"),
                        rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    replay = open_source(f"replay:{tmp_path}")
    with pytest.raises(InputError, match="trial entry 2: class number 2"):
        class_name(replay, 2)
    sim = open_source("sim")
    assert class_name(sim, 2) == sim.classes[1]
    with pytest.raises(InputError, match="trial entry 99: fabric number 99"):
        class_name(sim, 99)
