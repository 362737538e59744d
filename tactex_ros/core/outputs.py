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

import contextlib
import errno
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any
from collections.abc import Iterable

from .errors import InputError, TrialError


class WriteError(TrialError):
    """A file could not be written whole (disk full, file-size limit, I/O error): a run-time
    failure (exit status 1) naming the file and the reason; what was written before stays."""


def _why(exc: OSError) -> str:
    return exc.strerror or errno.errorcode.get(exc.errno or 0, "") or str(exc)


def write_fd(fd: int, data: bytes, path: str | Path) -> None:
    """Write all of ``data`` to ``fd``: a short ``os.write`` is continued, a write that makes
    no progress (a file-size limit, a full disk) or fails (ENOSPC, EFBIG, EIO) raises
    WriteError naming ``path``."""
    view = memoryview(data)
    while view:
        try:
            n = os.write(fd, view)
        except OSError as exc:
            raise WriteError(f"could not write {str(path)!r}: {_why(exc)} ({len(view)} of "
                             f"{len(data)} bytes not written)") from None
        if n <= 0:
            raise WriteError(f"could not write {str(path)!r}: no progress ({len(view)} of "
                             f"{len(data)} bytes not written; disk full or file-size limit)")
        view = view[n:]


def fsync_write(path: str | Path, data: bytes, append: bool) -> None:
    """Write ``data`` whole to ``path`` (appended, or replacing its content) and fsync it.
    On a failure the file is put back as it was (an appended tail is cut off, a new file
    removed) where that is still possible, and WriteError names the path."""
    p = Path(path)
    try:
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | (os.O_APPEND if append else os.O_TRUNC),
                     0o644)
    except OSError as exc:
        raise WriteError(f"could not open {str(p)!r} for writing: {_why(exc)}") from None
    try:
        size = os.fstat(fd).st_size
        try:
            write_fd(fd, data, p)
            os.fsync(fd)
        except (WriteError, OSError) as exc:
            try:
                if append:
                    os.ftruncate(fd, size)      # no torn line left behind
                else:
                    os.unlink(p)                # no torn file left behind
            except OSError:
                pass
            if isinstance(exc, WriteError):
                raise
            raise WriteError(f"could not write {str(p)!r}: {_why(exc)}") from None
    finally:
        os.close(fd)


def free_bytes(path: str | Path) -> int:
    """Free space [bytes] for an unprivileged writer on the file system of ``path`` (or of
    its nearest existing folder)."""
    return shutil.disk_usage(_nearest_existing(Path(path).absolute())).free


def check_free(path: str | Path, min_free_mb: float, what: str) -> None:
    """WriteError when less than ``min_free_mb`` [MB] are free where ``path`` is written."""
    if min_free_mb <= 0:
        return
    free = free_bytes(path)
    if free < min_free_mb * 1e6:
        raise WriteError(f"{what}: only {free / 1e6:.1f} MB free on the disk of {str(path)!r}, "
                         f"below min_free_mb ({min_free_mb:g} MB): free space first")


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
    """Write ``data`` whole and atomically (temporary file in the same folder, fsync,
    ``os.replace``); folders are made. WriteError (a TrialError) names the path when the
    data cannot be written whole; the previous file, if any, is left as it was."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    except OSError as exc:
        raise WriteError(f"could not write {str(p)!r}: {_why(exc)}") from None
    try:
        try:
            write_fd(fd, data, p)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.chmod(tmp, 0o644)
        os.replace(tmp, p)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise WriteError(f"could not write {str(p)!r}: {_why(exc)}") from None
        raise
    return p


def write_json(path: str | Path, obj: Any, indent: int | None = 2) -> Path:
    """Write ``obj`` as strict indented JSON, atomically; returns the path."""
    return write_bytes(path, dumps(obj, indent).encode())


def read_npz(path: str | Path, what: str, fmt: str, remedy: str) -> dict[str, Any]:
    """The arrays of the numpy ``.npz`` archive ``path`` (read with ``allow_pickle=False``)
    whose ``format`` field is ``fmt``; InputError naming ``what``, the path and ``remedy``
    when it is absent, torn, foreign or of another format."""
    import numpy as np
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{what} not found: {p}")
    try:
        with np.load(p, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
    except Exception as exc:  # numpy raises several types for a corrupt or foreign file
        raise InputError(f"{what} {p} is not loadable ({exc}); {remedy}") from None
    if str(d.get("format", "")) != fmt:
        raise InputError(f"{what} {p}: not a {fmt} file; {remedy}")
    return d
