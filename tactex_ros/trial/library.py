"""The session's hook to the fabric library (``core/library.py``): a finished trial whose
placement is known teaches the library in the background; the next trial sees the result.

``LibraryKeeper.learn`` starts a thread that reads the trial's record (accepted touches, their
images, further in-contact frames and no-contact frames), describes each touch as the trial's learner did
(``core.descriptor.raw_descriptor``), files it under the fabric its platform held and writes
the library file whole (``core.outputs.write_bytes``): a few seconds, while the operator places
the next trial's fabrics; no press waits for it. ``current`` waits for that update (at most
``wait_s``) before the next trial builds its engine, so every trial sees a definite library
state, which its record keeps (``fabric_library`` in result.json).
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from collections.abc import Callable

import numpy as np

from ..core import library as flib
from ..core.config import DescriptorSettings
from ..core.errors import TrialError
from ..core.descriptor import raw_descriptor
from ..core.touch import Touch
from .record import read_record


def trial_presses(record_dir: str | Path, placement: dict[str, str], cfg: DescriptorSettings,
                  tag: str) -> dict[str, tuple[np.ndarray, list[str]]]:
    """{fabric: ((n, D) raw descriptors, sources)} of the accepted touches of the trial record
    ``record_dir``, each under the fabric ``placement`` (platform id -> fabric) puts on its
    platform; a source is ``<tag>/touch <seq>``."""
    out: dict[str, tuple[list, list]] = {}
    for t in read_record(record_dir)["touches"]:
        fabric = placement.get(str(t.get("platform_id")))
        if not t.get("accepted") or t.get("array") is None or fabric is None:
            continue
        extra = [f for f in t.get("extra_arrays") or [] if f is not None]
        x = raw_descriptor(Touch(t["array"], t.get("no_contact_array"),
                                 np.stack(extra) if extra else None), cfg)
        xs, srcs = out.setdefault(fabric, ([], []))
        xs.append(x)
        srcs.append(f"{tag}/touch {t['seq']}")
    return {f: (np.stack(xs), srcs) for f, (xs, srcs) in out.items()}


class LibraryKeeper:
    """The library file ``path`` of a lab, kept up to date by the trials of a session.

    ``log(level, text)``: where an update's outcome goes; ``wait_s``: how long ``current``
    waits for an update still under way before the next trial uses the last written state."""

    def __init__(self, path: str | Path, cfg: DescriptorSettings,
                 log: Callable[[int, str], None] | None = None, wait_s: float = 120.0) -> None:
        self.path = Path(path)
        self.cfg = cfg
        self.wait_s = float(wait_s)
        self.log = log or (lambda level, text: logging.getLogger("tactex.library").log(
            level, text))
        self.library = flib.load(self.path, missing_ok=True)   # a torn file: InputError, exit 2
        self._thread: threading.Thread | None = None
        self.last_update: dict | None = None

    def learn(self, record_dir: str | Path, placement: dict[str, str], tag: str) -> None:
        """Start adding the trial ``record_dir``'s presses (background thread)."""
        self.current()                       # one update at a time, in trial order
        self._thread = threading.Thread(target=self._update, name="fabric-library",
                                        args=(Path(record_dir), dict(placement), tag),
                                        daemon=True)
        self._thread.start()

    def _update(self, record_dir: Path, placement: dict[str, str], tag: str) -> None:
        t0 = time.monotonic()
        try:
            lib = self.library
            for fabric, (x, srcs) in sorted(trial_presses(record_dir, placement, self.cfg,
                                                          tag).items()):
                lib = lib.add(fabric, x, srcs)
            added = lib.presses - self.library.presses
            if added:
                flib.save(lib, self.path)
            self.library = lib
            self.last_update = {"trial": tag, "added": added, **lib.state(),
                                "seconds": time.monotonic() - t0}
            self.log(logging.INFO, f"fabric library {self.path}: +{added} presses of trial "
                                   f"{tag} in {self.last_update['seconds']:.1f} s: "
                                   f"{lib.presses} presses of {len(lib.fabrics)} fabrics")
        except Exception as exc:  # noqa: BLE001 - the trial's record is the ground truth
            self.last_update = {"trial": tag, "error": f"{type(exc).__name__}: {exc}"}
            self.log(logging.ERROR, f"fabric library not updated from trial {tag}: {exc}")

    def current(self) -> flib.FabricLibrary:
        """The library after the update under way (waited for up to ``wait_s``). TrialError
        naming the file when that update failed (the file not written, a record unreadable):
        the session ends with a run-time failure (exit status 1) rather than go on with a
        library that silently lacks a trial; a continued session files it again."""
        th = self._thread
        if th is not None:
            th.join(self.wait_s)
            if th.is_alive():
                self.log(logging.WARNING, f"fabric library update still running after "
                                          f"{self.wait_s:g} s: this trial uses the state before")
            else:
                self._thread = None
                last = self.last_update or {}
                if "error" in last:
                    raise TrialError(f"fabric library {str(self.path)!r} not updated with the "
                                     f"presses of trial {last['trial']}: {last['error']}")
        return self.library
