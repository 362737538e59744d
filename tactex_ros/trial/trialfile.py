"""Trial files: fixed scenes of reference + comparison platforms (the thesis's human study).

Format (YAML)::

    name: human_study
    trials:
      - {id: 1, reference: 23, comparisons: [4, 8, 23, 7]}
      - {id: 2, reference: wool_jersey, comparisons: [wool_jersey, polar_fleece, ...]}

``id`` any scalar, unique (kept as a string); ``reference`` and every comparison are either an
integer (a fabric number of the catalogue ``config/fabrics.yaml``) or a class name. The reference
must be one of the comparisons: that platform is the true match. Read by the study session
(``tactex_ros.trial.session``) and by the offline experiments.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.paths import config_file, read_yaml
from .record import name_problem


def find_trial_file(spec: str | None) -> Path:
    """A path, or a name under ``config/trials`` (``human_study`` = the default)."""
    return config_file(spec or "human_study", "trials", "trial file")


def load_trials(path: str | Path) -> dict[str, Any]:
    """{"name", "path", "trials": [{"id": str, "reference", "comparisons": [...]}, ...]}."""
    path = Path(path)
    doc = read_yaml(path, "trial file")
    if not isinstance(doc, dict) or not isinstance(doc.get("trials"), list) or not doc["trials"]:
        raise InputError(f"trial file {path}: needs a non-empty list 'trials'")
    seen: set[str] = set()
    trials = []
    for i, t in enumerate(doc["trials"]):
        where = f"trial file {path}, entry {i + 1}"
        if not isinstance(t, dict) or not {"id", "reference", "comparisons"} <= set(t):
            raise InputError(f"{where}: needs id, reference and comparisons")
        tid = str(t["id"])
        why = name_problem(tid, folder=False)
        if why:
            raise InputError(f"{where}: id {tid!r}: {why}; an id is a plain name (letters, "
                             "digits, spaces inside, punctuation)")
        if tid in seen:
            raise InputError(f"{where}: duplicate id {tid!r}")
        seen.add(tid)
        comps = t["comparisons"]
        if not isinstance(comps, list) or len(comps) < 2:
            raise InputError(f"{where} (id {tid}): comparisons must list >= 2 classes")
        if t["reference"] not in comps:
            raise InputError(f"{where} (id {tid}): reference {t['reference']!r} is not among "
                              f"the comparisons {comps}")
        trials.append({"id": tid, "reference": t["reference"], "comparisons": list(comps)})
    return {"name": str(doc.get("name", path.stem)), "path": str(path), "trials": trials}
