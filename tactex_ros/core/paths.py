"""Where the package's shared files (``config/``) are, in a source tree or an install, and how a
file is named there: a path, or a name under one of its folders."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from .errors import InputError


def config_dir() -> Path:
    """``$TACTEX_CONFIG_DIR``, the source tree's ``config/`` (also reached through colcon's
    symlink install), ``<prefix>/share/tactex/config``, or the ament index's share directory."""
    cands: list[Path] = []
    if os.environ.get("TACTEX_CONFIG_DIR"):
        cands.append(Path(os.environ["TACTEX_CONFIG_DIR"]))
    cands.append(Path(__file__).resolve().parents[2] / "config")
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


def cache_dir() -> Path:
    """Where tactex keeps what it can rebuild (the simulator's fabric tiles):
    ``$XDG_CACHE_HOME/tactex``, by default ``~/.cache/tactex``. Not created here."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "tactex"


def config_names(folder: str) -> list[str]:
    """Names of the YAML files in ``config/<folder>`` (without ``.yaml``)."""
    return sorted(p.stem for p in (config_dir() / folder).glob("*.yaml"))


def config_file(name_or_path: str, folder: str, what: str) -> Path:
    """An existing file as given, else ``config/<folder>/<name>`` or ``<name>.yaml`` (for a name
    without ``/``); InputError naming ``what``, where it looked and the names available."""
    if not name_or_path:
        raise InputError(f"{what}: empty; give a name from config/{folder}/ or a path")
    p = Path(name_or_path)
    if p.is_file():
        return p
    if "/" not in name_or_path:
        for cand in (config_dir() / folder / name_or_path,
                     config_dir() / folder / f"{name_or_path}.yaml"):
            if cand.is_file():
                return cand
    raise InputError(f"{what} {name_or_path!r} not found (a path, or a name in "
                     f"{config_dir() / folder}: {', '.join(config_names(folder))})")


def read_yaml(path: str | Path, what: str) -> Any:
    """The YAML document of a file; InputError naming ``what`` and the file if it cannot be
    read or parsed."""
    import yaml
    try:
        return yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"{what} {str(path)!r}: not readable YAML ({exc})") from None
