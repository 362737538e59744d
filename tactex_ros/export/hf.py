"""A Hugging Face dataset of touches (``rows.collect``): ``<out>/data/train-*.parquet`` and
the dataset card ``<out>/README.md``, the layout of a dataset repository on the Hub, so
``datasets.load_dataset(out)`` loads it here and after ``huggingface-cli upload``.

Images are ``datasets.Image`` columns holding the record's PNG bytes unchanged (lossless; a
video codec would smear the fabric's micro-texture); ``material`` is a ``datasets.ClassLabel``
over the export's materials (-1 where the scene names none). ``datasets`` and ``pyarrow`` are
imported only by this module (``tactex export``), so the product starts without them.

The card's front matter is the Hub's (``huggingface_hub.DatasetCardData`` with ``datasets``'
``configs`` and ``dataset_info`` blocks): the licence (``DATA_LICENSE`` for what tactex
recorded; a ``replay:DIR`` library keeps its own), the one config, named after the data's
fingerprint (``datasets`` caches a local folder by its name and config: two exports in folders
of the same name never share a cache entry), the features, split sizes and the tactex version
and commit that wrote it. No path of the exporting machine is written: the source and every
path in the trials' settings by its last component only, no host name.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform as _platform
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.outputs import WriteError, write_bytes
from .rows import FIELDS, Trial, collect

BATCH = 64          # rows per parquet row group (images are held in memory one batch at a time)
DATA_FILE = "data/train-00000-of-00001.parquet"
#: the licence of the data tactex records (trial records, sessions): Creative Commons
#: Attribution 4.0, the Hub's identifier; a library of someone else's presses keeps theirs
DATA_LICENSE = "cc-by-4.0"
_PATHLIKE = re.compile(r"(?<![\w.])(?:~|/)[^\s'\",;]*")   # "/a/b", "~/x" in a string


def features(materials: list[str]):
    """The columns' ``datasets.Features`` (``rows.FIELDS``); ``material`` a ``ClassLabel`` of
    ``materials``."""
    from datasets import ClassLabel, Features, Image, Sequence, Value
    s, f, i = Value("string"), Value("float64"), Value("int32")
    return Features({
        "trial_id": s, "session": s, "seq": i, "platform_id": s, "platform_index": i,
        "material": ClassLabel(names=materials), "image": Image(), "no_contact": Image(),
        "extra": Sequence(Image()),
        "force_n": f, "depth_m": f,
        "pose": Sequence(f), "press_time": f, "accepted": Value("bool"), "reason": s,
        "next_platform": s, "belief": Sequence(f), "belief_platforms": Sequence(s),
        "prediction": s, "prediction_material": s, "reference_material": s,
        "correct": Value("bool"), "stop_reason": s, "source_file": s})


def _image(b: bytes | None) -> dict | None:
    return None if b is None else {"bytes": b, "path": None}


def export(source: str, out: str | Path) -> dict[str, Any]:
    """Write the dataset of ``source`` (a record, a session, a folder of them, ``replay:DIR``)
    into the new (or empty) folder ``out``; returns what the card says (kind, trials, rows).

    The dataset is written into a temporary folder beside ``out`` and renamed to ``out`` once
    whole: a write that fails (a full disk, a file-size limit) leaves nothing in ``out`` and
    no temporary folder, so the same command can run again (WriteError naming the file)."""
    try:
        import datasets
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise InputError(f"tactex export needs the datasets package ({exc}); pip install "
                         "-r requirements.txt") from None
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"--out {str(out)!r} is not an empty folder: an export goes into a "
                         "new folder")
    kind, trials = collect(source)
    rows_n = sum(len(t.rows) for t in trials)
    if rows_n == 0:
        raise InputError(f"export: {source!r} holds no touch")
    materials = sorted({r["material"] for t in trials for r in t.rows if r["material"]})
    feats = features(materials)
    info: dict[str, Any] = {"kind": kind, "source": _public(source), "trials": len(trials),
                            "rows": rows_n, "datasets": datasets.__version__,
                            "materials": materials}
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    except OSError as exc:
        raise WriteError(f"could not write in {str(out.parent)!r}: {exc.strerror or exc}") \
            from None
    what = out / DATA_FILE
    try:
        info["num_bytes"] = _write_rows(trials, tmp / DATA_FILE, feats, pq, datasets)
        with open(tmp / DATA_FILE, "rb") as f:
            info["fingerprint"] = hashlib.file_digest(f, "sha256").hexdigest()[:16]
        info["download_size"] = (tmp / DATA_FILE).stat().st_size
        info["config"] = f"tactex-{info['fingerprint']}"
        what = out / "README.md"
        write_bytes(tmp / "README.md", card(info, trials, feats).encode())
        what = out
        if out.exists():
            out.rmdir()                     # empty (checked above): the dataset takes its place
        os.replace(tmp, out)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, (OSError, WriteError)):
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            raise WriteError(f"could not write {str(what)!r}: {why}; nothing was left in "
                             f"{str(out)!r}") from None
        raise
    return info


def _write_rows(trials: list[Trial], path: Path, feats, pq, datasets) -> int:
    """Every trial's rows into the parquet file ``path`` (``BATCH`` rows per row group);
    returns their size in memory (arrow bytes, the card's ``num_bytes``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = None
    nbytes = 0
    try:
        batch: list[dict] = []
        for row in (r for t in trials for r in t.rows):
            batch.append(dict(row, image=_image(row["image"]),
                              no_contact=_image(row["no_contact"]),
                              extra=[_image(b) for b in row["extra"]],
                              material=row["material"] or -1))
            if len(batch) == BATCH:
                writer, n = _write(writer, batch, feats, path, pq, datasets)
                nbytes += n
                batch = []
        if batch:
            writer, n = _write(writer, batch, feats, path, pq, datasets)
            nbytes += n
    finally:
        if writer is not None:
            writer.close()
    return nbytes


def _write(writer, batch: list[dict], feats, path: Path, pq, datasets) -> tuple[Any, int]:
    """Append ``batch`` to the parquet file ``path``; (the writer, the batch's arrow bytes)."""
    table = datasets.Dataset.from_list(batch, features=feats).with_format("arrow")[:]
    table = table.replace_schema_metadata(feats.arrow_schema.metadata)
    if writer is None:
        writer = pq.ParquetWriter(str(path), table.schema)
    writer.write_table(table)
    return writer, table.nbytes


def _public(value: Any) -> Any:
    """``value`` (a string or a JSON-like tree of settings) with every path of this machine
    in it cut to its last component and host names left out: what a card may say of the
    machine that wrote it. A path of the machine: ``~/...``, or an absolute path whose first
    component is an entry of ``/`` here (``/home/..``, ``/tmp/..``); a ROS name such as
    ``/tactex/state`` is kept."""
    if isinstance(value, dict):
        return {k: _public(v) for k, v in value.items() if k != "host"}
    if isinstance(value, list):
        return [_public(v) for v in value]
    if not isinstance(value, str):
        return value
    import os
    roots = set(os.listdir("/"))

    def cut(m: re.Match) -> str:
        text = m.group(0)
        first = text[1:].split("/")[0] if text.startswith("/") else ""
        if text.startswith("~") or first in roots:
            return Path(text.rstrip("/")).name or text
        return text
    return _PATHLIKE.sub(cut, value)


def _versions() -> dict[str, str]:
    from importlib import metadata
    from ..trial.report import run_info
    out = {"python": _platform.python_version(), "tactex commit": run_info()["commit"]}
    for pkg in ("tactex", "datasets", "numpy", "opencv-python-headless"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            continue
    return out


def front_matter(info: dict[str, Any], feats) -> str:
    """The card's YAML front matter (without the ``---`` lines): licence, task, tags, the
    config and its ``dataset_info`` (features, the train split's bytes and rows)."""
    from datasets import DatasetInfo, SplitDict, SplitInfo
    from datasets.info import DatasetInfosDict
    from datasets.utils.metadata import MetadataConfigs
    from huggingface_hub import DatasetCardData
    from ..trial.report import run_info
    run = run_info()
    library = info["kind"] == "library"
    data = DatasetCardData(
        license="other" if library else DATA_LICENSE,
        license_name="the source library's licence" if library else None,
        task_categories=["image-classification"], tags=["tactile", "gelsight", "robotics"],
        pretty_name=f"tactex touches ({info['kind']})",
        tactex={"version": run["version"], "commit": run["commit"] or None,
                "fingerprint": info["fingerprint"]})
    config = info["config"]
    MetadataConfigs({config: {"data_files": [{"split": "train", "path": DATA_FILE}]}}
                    ).to_dataset_card_data(data)
    splits = SplitDict()
    splits.add(SplitInfo(name="train", num_bytes=info["num_bytes"], num_examples=info["rows"]))
    DatasetInfosDict({config: DatasetInfo(features=feats, splits=splits,
                                          download_size=info["download_size"],
                                          dataset_size=info["num_bytes"])}
                     ).to_dataset_card_data(data)
    return data.to_yaml().rstrip("\n") + "\n"


def card(info: dict[str, Any], trials: list[Trial], feats) -> str:
    """The dataset card: YAML front matter (``front_matter``), what the data is and under
    which licence, the columns, each trial's settings and result (no machine path), the
    versions and commit it was made with."""
    cols = "\n".join(f"| `{k}` | {v} |" for k, v in FIELDS.items())
    settings = {t.name: _public({"config": t.config, "result": t.result}) for t in trials
                if t.config or t.result}
    materials = info["materials"]
    licence = ("The presses are the source library's: its licence applies."
               if info["kind"] == "library" else
               f"Licence: {DATA_LICENSE} (Creative Commons Attribution 4.0), tactex's choice "
               "for the data it records.")
    return f"""---
{front_matter(info, feats)}---

# tactex touches ({info['kind']})

Exported by `tactex export` on {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())} from
`{info['source']}`: {info['trials']} {'class folder(s)' if info['kind'] == 'library' else 'trial(s)'},
{info['rows']} touches, one row per touch. Images are the sensor's frames as lossless PNG
(RGB, 320x240 for a GelSight Mini). {licence}

```python
from datasets import load_dataset
ds = load_dataset("path/to/this/folder", split="train")     # config {info['config']}
ds[0]["image"]          # PIL image of the first touch
ds.features["material"].int2str(ds[0]["material"])          # its material (-1: unknown)
```

Materials (`material`, a ClassLabel in this order): {', '.join(materials) if materials else 'not known to the scene'}.

## Columns

| column | meaning |
| --- | --- |
{cols}

## Settings and results of each trial

```json
{json.dumps(settings, indent=1, sort_keys=True, default=str)}
```

## Versions

```json
{json.dumps(_versions(), indent=1, sort_keys=True)}
```
"""
