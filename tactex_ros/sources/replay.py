"""Touch source that replays real GelSight press recordings.

Folder layout: ``<root>/<class>/<file>`` (hidden folders, ``.name``, are no class); each file is one press, a video readable by OpenCV
(``.mov .mp4 .avi .mkv``) or a single image (``.png .jpg .jpeg .bmp``). For a video the contact
frame is chosen deliberately: the strongest contact against the press's own no-contact frames
(see ``core.contact``). A touch is a ``core.touch.Touch``: that frame, the press's no-contact
frame (median of its first 3 frames) and up to ``core.contact.EXTRA_FRAMES`` more in-contact
frames at other depths (``core.contact.in_contact``: a contact score at least ``CONTACT_SHARE``
of the strongest; evenly spaced in time). The live sensor's burst uses the same rule
(``robot/frames.py``). An image file gives a touch without a no-contact frame. Frames are RGB uint8
(240, 320, 3).

Every press file is judged when the source opens (``check_press_files``): an empty file, one
that does not decode, a video whose frames do not all decode (garbled or cut: fewer than its
container declares) or a frame smaller than the sensor's refuses the source (InputError naming
each such file), rather than failing the touch that draws it. A file damaged after the source
opened is still a failed touch of that trial.

A trial assigns a class to the reference and to every comparison platform. Touching a platform
draws a press of its class not used yet in this trial, in a seeded random order, cycling when
the class is exhausted. Presses used for the reference are never handed to a comparison platform
while unused presses of the class remain (no test press leaks into training).

Recorded datasets press each class in its own session (octopi-dev: the no-contact frame alone
names a press's class for 75 % of presses, README "Recording sessions"), so a model that sees
whole frames can match platforms by their session instead of their texture; a live robot
presses every platform in one session. ``one_session`` (spec ``replay:DIR:one-session``) replays
the presses as if recorded in one session: every frame of a press is moved onto the trial's
background, ``frame - own no-contact frame + background`` (the background: the no-contact frame
of the trial's first touch), and carries that background as its no-contact frame.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from ..core.contact import EXTRA_FRAMES, in_contact, strongest_contact, to_sensor_frame
from ..core.errors import InputError
from ..core.touch import Touch

VIDEO_EXT = {".mov", ".mp4", ".avi", ".mkv"}
IMAGE_EXT = {".png", ".jpg", ".jpeg", ".bmp"}


def _frame_count_problem(declared: int, decoded: int) -> str | None:
    """Why a video that decoded ``decoded`` frames is damaged (None: it is whole): fewer than
    2 frames, or fewer than its container declares (``declared`` <= 0: not declared; one
    frame of slack for a count the container estimates from its duration)."""
    if decoded < 2:
        return ("unreadable video (no frames decoded)" if decoded == 0 else
                f"unreadable video (only {decoded} frame decoded)")
    if declared > 0 and decoded < declared - 1:
        return (f"garbled or cut video: {decoded} of the {declared} frames its container "
                "declares decode")
    return None


def read_video(path: str | Path) -> np.ndarray:
    """All frames of a video as sensor-sized BGR uint8 (F, 240, 320, 3); InputError if fewer
    than 2 decode, or fewer than the container declares (a garbled or cut file)."""
    cap = cv2.VideoCapture(str(path))
    frames = []
    try:
        declared = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else 0
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            try:
                frames.append(to_sensor_frame(frame))
            except InputError as exc:
                raise InputError(f"press file {path}: {exc}") from None
    finally:
        cap.release()
    problem = _frame_count_problem(declared, len(frames))
    if problem:
        raise InputError(f"{problem}: {path}")
    return np.stack(frames)


@lru_cache(maxsize=4096)
def _judge(path: str, size: int, mtime_ns: int) -> str | None:
    """Why the press file ``path`` (of ``size`` bytes, modified at ``mtime_ns``: a file
    changed since is judged again) cannot be replayed, or None: empty, not decodable, a frame
    smaller than the sensor's, a video whose frames do not all decode. A video's frames are
    decoded (``grab``) but not converted: about 10 ms a press."""
    p = Path(path)
    if size == 0:
        return f"press file {p} is empty (0 bytes)"
    if p.suffix.lower() in IMAGE_EXT:
        img = cv2.imread(path, cv2.IMREAD_COLOR)
        if img is None:
            return f"unreadable image file: {p}"
        first = img
    else:
        cap = cv2.VideoCapture(path)
        try:
            if not cap.isOpened():
                return f"unreadable video (the file does not open as a video): {p}"
            declared = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            ok, first = cap.read()
            decoded = int(ok)
            while ok and cap.grab():
                decoded += 1
        finally:
            cap.release()
        problem = _frame_count_problem(declared, decoded)
        if problem:
            return f"{problem}: {p}"
    try:
        to_sensor_frame(first)
    except InputError as exc:
        return f"press file {p}: {exc}"
    return None


def check_press_files(files: list[Path]) -> None:
    """InputError naming every press file of ``files`` that cannot be replayed whole
    (``_judge``: empty, undecodable, garbled or cut, too small); nothing when all can."""
    bad = []
    for f in files:
        try:
            st = f.stat()
        except OSError as exc:
            bad.append(f"press file {f}: {exc.strerror or exc}")
            continue
        why = _judge(str(f), st.st_size, st.st_mtime_ns)
        if why:
            bad.append(why)
    if bad:
        raise InputError(f"{len(bad)} of {len(files)} press file(s) cannot be replayed: "
                         + "; ".join(bad[:5]) + (" ..." if len(bad) > 5 else "")
                         + " (repair or remove them)")


def load_press(path: str) -> tuple[np.ndarray, float]:
    """(contact frame RGB uint8 (240, 320, 3), contact score in grey levels) of one press file."""
    touch, score = load_touch(path)
    return touch.frame, score


@lru_cache(maxsize=512)
def load_touch(path: str) -> tuple[Touch, float]:
    """(the press as a Touch, contact score of its strongest frame [grey levels])."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext in IMAGE_EXT:
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if img is None:
            raise InputError(f"unreadable image file: {p}")
        try:
            frame = to_sensor_frame(img)
        except InputError as exc:
            raise InputError(f"press file {p}: {exc}") from None
        return Touch(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)), float("nan")
    arr = read_video(p)
    idx, scores = strongest_contact(arr)
    strong = np.flatnonzero(in_contact(scores, idx))
    strong = strong[strong != idx]
    pick = (strong[np.round(np.linspace(0, len(strong) - 1, EXTRA_FRAMES)).astype(int)]
            if len(strong) > EXTRA_FRAMES else strong)
    rgb = arr[..., ::-1]
    touch = Touch(frame=np.ascontiguousarray(rgb[idx]),
                  no_contact=np.median(rgb[:3], axis=0).astype(np.uint8),
                  extra=np.ascontiguousarray(rgb[np.unique(pick)]) if len(pick) else None)
    return touch, float(scores[idx])


class ReplaySource:
    """A folder of recorded presses, one subfolder per class (``sources.base.TouchSource``)."""

    def __init__(self, root: str | Path, one_session: bool = False) -> None:
        self.root = Path(root)
        self.one_session = one_session
        if not self.root.is_dir():
            raise InputError(f"replay folder does not exist: {self.root}")
        self.files: dict[str, list[Path]] = {}
        for d in sorted(self.root.iterdir()):
            if not d.is_dir() or d.name.startswith("."):
                continue           # a hidden folder is no class (a press library's logs)
            files = sorted(f for f in d.iterdir()
                           if f.is_file() and f.suffix.lower() in VIDEO_EXT | IMAGE_EXT)
            self.files[d.name] = files
        if not any(self.files.values()):
            raise InputError(f"replay folder {self.root} has no <class>/<press file> entries "
                             f"(videos {sorted(VIDEO_EXT)} or images {sorted(IMAGE_EXT)})")
        try:                       # every press judged now, not at the touch that draws it
            check_press_files([f for fs in self.files.values() for f in fs])
        except InputError as exc:
            raise InputError(f"replay folder {self.root}: {exc}") from None

    @property
    def classes(self) -> list[str]:
        """Classes with at least one press file."""
        return [c for c, f in self.files.items() if f]

    @property
    def known_classes(self) -> list[str]:
        return self.classes

    def by_number(self, number: int) -> str:
        raise InputError(f"class number {number}: numbers name the simulator's catalogue "
                         "fabrics (source sim); name the classes of this source instead")

    def draw_scene(self, comparisons: int, seed: int) -> None:
        """Scenes are drawn from ``classes``."""
        return None

    def no_contact(self, seed: int) -> None:
        """Every recorded press brings its own no-contact frame."""
        return None

    def presses(self, cls: str) -> list[Path]:
        if cls not in self.files:
            raise InputError(f"class {cls!r} not in replay folder {self.root}; "
                             f"available: {', '.join(self.classes)}")
        if not self.files[cls]:
            raise InputError(f"class {cls!r} in {self.root} has no readable press file")
        return self.files[cls]

    def frame(self, path: Path) -> np.ndarray:
        """The strongest-contact frame of one press file."""
        return load_touch(str(path))[0].frame

    def touch(self, path: Path) -> Touch:
        """One press file as a Touch (contact frame, no-contact frame, more contact frames)."""
        return load_touch(str(path))[0]

    def check_class(self, cls: str) -> None:
        """Raise InputError unless at least one press of ``cls`` decodes."""
        errors = []
        for f in self.presses(cls):
            try:
                self.frame(f)
                return
            except InputError as exc:
                errors.append(str(exc))
        raise InputError(f"class {cls!r} has no readable press: {'; '.join(errors)}")

    def trial(self, platform_classes: list[str], seed: int,
              depth_spread_mm: float | None = None) -> ReplayTrial:
        """Touch function of one trial (``TouchSource.trial``): recorded presses drawn without
        repetition where possible."""
        if depth_spread_mm is not None:
            raise InputError(f"depth spread {depth_spread_mm} mm: recorded presses have their "
                             "own depths; the depth perturbation needs the simulator (sim)")
        return ReplayTrial(self, platform_classes, seed)


class ReplayTrial:
    """Touch function of one trial: ``touch(platform) -> RGB frame``; platform 0 = reference."""

    def __init__(self, source: ReplaySource, platform_classes: list[str], seed: int) -> None:
        for c in set(platform_classes):
            source.check_class(c)
        self.source = source
        self.platform_classes = list(platform_classes)
        rng = np.random.default_rng([seed, 11])
        # sorted: a set's order changes between processes (string hashing is salted), and the
        # draws must not (same seed -> same presses, in every process)
        self._order = {c: list(rng.permutation(len(source.presses(c))))
                       for c in sorted(set(platform_classes))}
        self._used: dict[str, list[int]] = {c: [] for c in set(platform_classes)}
        self._reference_used: set[int] = set()
        self.log: list[tuple[int, str]] = []   # (platform, file) per touch
        self._background: np.ndarray | None = None    # one_session: the trial's

    def _draw(self, cls: str, for_reference: bool) -> int:
        order, used = self._order[cls], self._used[cls]
        fresh = [i for i in order if i not in used]
        if not for_reference:
            fresh = [i for i in fresh if i not in self._reference_used]
        if not fresh:  # exhausted: cycle, still avoiding the reference's presses if possible
            pool = [i for i in order if i not in self._reference_used] or order
            fresh = sorted(pool, key=lambda i: used.count(i))[:1]
        i = fresh[0]
        used.append(i)
        if for_reference:
            self._reference_used.add(i)
        return i

    def __call__(self, platform: int) -> Touch:
        cls = self.platform_classes[platform]
        i = self._draw(cls, platform == 0)
        path = self.source.presses(cls)[i]
        self.log.append((platform, str(path)))
        try:
            touch = self.source.touch(path)
        except InputError as exc:     # a file damaged since the source opened: a failed
            from ..core.engine import TouchFailed     # touch, the engine draws another press
            raise TouchFailed(str(exc)) from exc
        if not self.source.one_session or touch.no_contact is None:
            return touch
        if self._background is None:
            self._background = touch.no_contact
        return rebase(touch, self._background)


def rebase(touch: Touch, background: np.ndarray) -> Touch:
    """``touch`` moved onto ``background`` (uint8 RGB (240, 320, 3)): every frame minus the
    touch's no-contact frame plus ``background``, saturated; its no-contact frame becomes
    ``background``. A touch without a no-contact frame is returned as it is."""
    if touch.no_contact is None:
        return touch
    shift = background.astype(np.int16) - touch.no_contact.astype(np.int16)

    def move(f: np.ndarray) -> np.ndarray:
        return np.clip(f.astype(np.int16) + shift, 0, 255).astype(np.uint8)

    return Touch(frame=move(touch.frame), no_contact=background,
                 extra=None if touch.extra is None else np.stack([move(f) for f in touch.extra]))
