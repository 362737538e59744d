"""Where the package's shared files (``config/``) are, in a source tree or an install."""

from __future__ import annotations

import os
import sys
from pathlib import Path


def config_dir() -> Path:
    """``$TACTEX_CONFIG_DIR``, the source tree's ``config/`` (also reached through colcon's
    symlink install), ``<prefix>/share/tactex/config``, or the ament index's share directory."""
    cands: list[Path] = []
    if os.environ.get("TACTEX_CONFIG_DIR"):
        cands.append(Path(os.environ["TACTEX_CONFIG_DIR"]))
    cands.append(Path(__file__).resolve().parent.parent / "config")
    cands.append(Path(sys.prefix) / "share" / "tactex" / "config")
    try:
        from ament_index_python.packages import get_package_share_directory
        cands.append(Path(get_package_share_directory("tactex")) / "config")
    except Exception:  # noqa: BLE001 - ament index absent (pip install) or package not found
        pass
    for c in cands:
        if (c / "fabrics.yaml").is_file():
            return c
    raise FileNotFoundError(f"tactex config directory not found; looked in {cands}")
