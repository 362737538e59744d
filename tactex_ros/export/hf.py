"""A Hugging Face dataset of touches (``rows.collect``): ``<out>/data/train-*.parquet`` and
the dataset card ``<out>/README.md``, the layout of a dataset repository on the Hub, so
``datasets.load_dataset(out)`` loads it here and after ``huggingface-cli upload``.

Images are ``datasets.Image`` columns holding the record's PNG bytes unchanged (lossless; a
video codec would smear the fabric's micro-texture). ``datasets`` and ``pyarrow`` are imported
only by this module (``tactex export``), so the product starts without them.
"""

from __future__ import annotations

import json
import os
import platform as _platform
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


def features():
    """The columns' ``datasets.Features`` (``rows.FIELDS``)."""
    from datasets import Features, Image, Sequence, Value
    s, f, i = Value("string"), Value("float64"), Value("int32")
    return Features({
        "trial_id": s, "session": s, "seq": i, "platform_id": s, "platform_index": i,
        "material": s, "image": Image(), "no_contact": Image(), "extra": Sequence(Image()),
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
    info = {"kind": kind, "source": source, "trials": len(trials), "rows": rows_n,
            "datasets": datasets.__version__}
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    except OSError as exc:
        raise WriteError(f"could not write in {str(out.parent)!r}: {exc.strerror or exc}") \
            from None
    what = out / DATA_FILE
    try:
        _write_rows(trials, tmp / DATA_FILE, pq, datasets)
        what = out / "README.md"
        write_bytes(tmp / "README.md", card(info, trials).encode())
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


def _write_rows(trials: list[Trial], path: Path, pq, datasets) -> None:
    """Every trial's rows into the parquet file ``path`` (``BATCH`` rows per row group)."""
    feats = features()
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = None
    try:
        batch: list[dict] = []
        for row in (r for t in trials for r in t.rows):
            batch.append(dict(row, image=_image(row["image"]),
                              no_contact=_image(row["no_contact"]),
                              extra=[_image(b) for b in row["extra"]]))
            if len(batch) == BATCH:
                writer = _write(writer, batch, feats, path, pq, datasets)
                batch = []
        if batch:
            writer = _write(writer, batch, feats, path, pq, datasets)
    finally:
        if writer is not None:
            writer.close()


def _write(writer, batch: list[dict], feats, path: Path, pq, datasets):
    table = datasets.Dataset.from_list(batch, features=feats).with_format("arrow")[:]
    table = table.replace_schema_metadata(feats.arrow_schema.metadata)
    if writer is None:
        writer = pq.ParquetWriter(str(path), table.schema)
    writer.write_table(table)
    return writer


def _versions() -> dict[str, str]:
    from importlib import metadata
    out = {"python": _platform.python_version()}
    for pkg in ("tactex", "datasets", "numpy", "opencv-python-headless"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            continue
    return out


def card(info: dict[str, Any], trials: list[Trial]) -> str:
    """The dataset card: YAML front matter (the Hub's ``configs`` and ``dataset_info``), what
    the data is, the columns, each trial's settings and result, the versions it was made
    with."""
    cols = "\n".join(f"| `{k}` | {v} |" for k, v in FIELDS.items())
    settings = {t.name: {"config": t.config, "result": t.result} for t in trials
                if t.config or t.result}
    materials = sorted({r["material"] for t in trials for r in t.rows if r["material"]})
    return f"""---
license: other
task_categories:
- image-classification
tags:
- tactile
- gelsight
- robotics
configs:
- config_name: default
  data_files:
  - split: train
    path: {DATA_FILE}
---

# tactex touches ({info['kind']})

Exported by `tactex export` on {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())} from
`{info['source']}`: {info['trials']} {'class folder(s)' if info['kind'] == 'library' else 'trial(s)'},
{info['rows']} touches, one row per touch. Images are the sensor's frames as lossless PNG
(RGB, 320x240 for a GelSight Mini).

```python
from datasets import load_dataset
ds = load_dataset("path/to/this/folder", split="train")
ds[0]["image"]          # PIL image of the first touch
```

Materials: {', '.join(materials) if materials else 'not known to the scene'}.

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
