"""The one way output files are checked and written: strict JSON, atomic writes, paths refused
before any work.

``check_file`` / ``check_dir`` refuse an output path that cannot be written (a parent that is a
file, a folder without write permission, a path that is a folder, a suffix the writer cannot
produce) with a ``InputError`` naming the option and the path, so a command fails in its first
second rather than after its work. ``write_json`` writes strict JSON (NaN and +-Infinity become
``null``: ``JSON.parse`` and other strict readers refuse them) through a temporary file in the
same folder and ``os.replace``, so a reader never sees a torn file.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Iterable

from .errors import InputError


def jsonable(o: Any) -> Any:
    """``o`` with numpy values as Python ones, paths as strings and every non-finite float
    (NaN, +-inf) as None; dict keys become strings, tuples and sets lists."""
    if isinstance(o, dict):
        return {str(k) if not isinstance(k, str) else k: jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple, set, frozenset)):
        return [jsonable(v) for v in o]
    if isinstance(o, bool) or o is None or isinstance(o, (str, int)):
        return o
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, Path):
        return str(o)
    tolist = getattr(o, "tolist", None)          # numpy arrays and scalars
    if callable(tolist):
        return jsonable(tolist())
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def dumps(obj: Any, indent: int | None = 2) -> str:
    """Strict JSON text of ``obj`` (see ``jsonable``); never contains NaN or Infinity."""
    return json.dumps(jsonable(obj), indent=indent, allow_nan=False)


def _nearest_existing(p: Path) -> Path:
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_dir(path: str | Path, what: str) -> Path:
    """A folder that exists and is writable, or can be made; InputError naming ``what`` and
    the path otherwise (nothing is left behind: a probe file is made and removed in the
    nearest existing folder)."""
    return _folder(Path(path).absolute(), what, str(path))


def _folder(p: Path, what: str, shown: str) -> Path:
    """``p`` (absolute) can be a folder we write into; errors show ``what`` and ``shown``."""
    if p.exists() and not p.is_dir():
        raise InputError(f"{what} {shown!r}: {str(p)!r} is a file, not a folder")
    base = _nearest_existing(p)
    if not base.is_dir():
        raise InputError(f"{what} {shown!r}: {str(base)!r} is a file, not a folder")
    try:      # a trial file: permissions, read-only and special file systems, also as root
        fd, probe = tempfile.mkstemp(prefix=".tactex-probe.", dir=base)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"{what} {shown!r}: cannot write in {str(base)!r} "
                          f"({exc.strerror or exc})") from None
    return p


def check_file(path: str | Path, what: str, suffixes: Iterable[str] = ()) -> Path:
    """An output file that can be written (its folder exists and is writable, or can be made;
    the path is not a folder; its suffix is one of ``suffixes`` when given); InputError naming
    ``what`` and the path otherwise."""
    p = Path(path)
    if not str(path) or p.name in ("", ".", ".."):
        raise InputError(f"{what} {str(path)!r}: not a file name")
    suffixes = tuple(s.lower() for s in suffixes)
    if suffixes and p.suffix.lower() not in suffixes:
        raise InputError(f"{what} {str(path)!r}: the file name must end in "
                          f"{' or '.join(suffixes)}")
    if p.is_dir():
        raise InputError(f"{what} {str(path)!r}: is a folder")
    if p.exists() and not os.access(p, os.W_OK):
        raise InputError(f"{what} {str(path)!r}: not writable")
    _folder(p.absolute().parent, what, str(path))
    return p


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` atomically (temporary file in the same folder, fsync, ``os.replace``);
    folders are made. OSError names the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return p


def write_json(path: str | Path, obj: Any, indent: int | None = 2) -> Path:
    """Write ``obj`` as strict indented JSON, atomically; returns the path."""
    return write_bytes(path, dumps(obj, indent).encode())
