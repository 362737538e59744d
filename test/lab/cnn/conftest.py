"""Tests marked ``gpu`` need a CUDA device: elsewhere they are skipped, the reason naming what
torch reports."""

from __future__ import annotations

import pytest


def pytest_runtest_setup(item: pytest.Item) -> None:
    if item.get_closest_marker("gpu") is None:
        return
    import torch
    if not torch.cuda.is_available():
        from tactex_lab.cnn.device import cuda_report
        pytest.skip(f"needs a CUDA device: {cuda_report()}")
