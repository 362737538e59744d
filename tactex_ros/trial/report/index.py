"""``tactex report FOLDER``: the reports of a trial record or a session folder written again
(``regenerate``)."""

from __future__ import annotations

from pathlib import Path

from ...core.errors import InputError
from .session_page import write_session_report
from .trial_page import write_trial_report


def regenerate(folder: str | Path) -> list[Path]:
    """``tactex report``: a trial record -> its report; a session folder -> every trial's
    report and the session report. InputError when ``folder`` is neither."""
    d = Path(folder)
    try:
        return _regenerate(d)
    except InputError:
        raise
    except (KeyError, TypeError, AttributeError, IndexError, ValueError) as exc:
        # a file of the folder holds other types than a record's: refused, not a traceback
        raise InputError(f"{str(d)!r}: a file of the record or session is damaged "
                         f"({type(exc).__name__}: {exc})") from None


def _regenerate(d: Path) -> list[Path]:
    from .. import session as sess
    if (d / sess.SESSION_FILE).is_file():
        out = [write_trial_report(p.parent) for p in sorted(d.glob("trial_*/config.json"))]
        return out + [write_session_report(d)]
    if (d / "config.json").is_file() or (d / "touches.jsonl").is_file():
        return [write_trial_report(d)]
    raise InputError(f"{str(d)!r} is neither a trial record (config.json, touches.jsonl) nor "
                      f"a session folder ({sess.SESSION_FILE})")
