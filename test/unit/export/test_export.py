"""``tactex export``: a simulated trial record, a study session and a library of recorded
presses written as a Hugging Face dataset and loaded back with ``datasets``: every image byte
for byte the record's PNG, every label the record's."""

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

datasets = pytest.importorskip("datasets")

from tactex_ros.cli.main import main  # noqa: E402
from tactex_ros.core.config import preset, trial_preset  # noqa: E402
from tactex_ros.core.engine import TrialSpec, run_trial  # noqa: E402
from tactex_ros.core.touch import Touch, as_touch  # noqa: E402
from tactex_ros.core.paths import config_dir  # noqa: E402
from tactex_ros.robot.scene import load_scene  # noqa: E402
from tactex_ros.sources import open_source  # noqa: E402
from tactex_ros.trial.record import TrialRecord, read_record  # noqa: E402
from tactex_ros.trial.session import open_session, load_session, placed_scene, record_name  # noqa: E402,E501

SCENE = config_dir() / "scene_sim.yaml"


def _trial(root: Path, trial_id: str, scene_text: str, seed: int) -> Path:
    """A simulated trial written as the explorer writes it: each touch (contact image and
    no-contact frame) on disk before it is used, each decision after it is made."""
    root.mkdir(parents=True, exist_ok=True)
    scene_file = root / f"{trial_id}.scene.yaml"
    scene_file.write_text(scene_text)
    scene = load_scene(scene_file)
    ids = [p.id for p in scene.ordered]
    classes = [p.sim_fabric for p in scene.ordered]
    src = open_source("sim")
    fn = src.trial(classes, seed)
    rec = TrialRecord(root, trial_id)
    rec.save_inputs(scene_file, {"trial": {"strategy": "infogain", "seed": seed}})
    spec = TrialSpec(len(ids) - 1, preset("default"),
                     trial_preset("default", rounds=3), seed=seed, platform_ids=tuple(ids))

    def touch(p: int) -> Touch:
        t = as_touch(fn(p))
        nc = t.no_contact if t.no_contact is not None else np.full_like(t.frame, 90)
        # a burst of p more frames of the press (the live capture's): none for the reference
        extra = np.stack([np.roll(t.frame, k, axis=1) for k in range(1, p + 1)]) if p else None
        rec.add_touch(t.frame, {"platform_id": ids[p], "platform_index": p, "accepted": True,
                                "force_n": 4.0 + p, "depth_m": 4e-4, "stamp": 100.0 + p,
                                "pose": [0.4, 0.1 * p, 0.08]}, no_contact=nc, extra=extra)
        return Touch(frame=t.frame, no_contact=nc, extra=extra)

    def decided(r) -> None:
        rec.add_decision({"round": r.round, "belief": list(r.probs),
                          "next": "" if r.platform is None else ids[r.platform],
                          "touches": list(r.touches)})
    res = run_trial(spec, touch, on_round=decided)
    rec.finish({"prediction": ids[res.prediction], "touches": res.touches,
                "stop_reason": res.stop_reason})
    return rec.dir


def _load(out: Path, tmp: Path):
    ds = datasets.load_dataset(str(out), split="train", cache_dir=str(tmp / "cache"))
    return ds.cast_column("image", datasets.Image(decode=False)).cast_column(
        "no_contact", datasets.Image(decode=False)).cast_column(
        "extra", datasets.Sequence(datasets.Image(decode=False)))


def _same_as_record(ds, d: Path, session: str = "") -> None:
    rows = [r for r in ds if r["trial_id"] == d.name]
    rec = read_record(d, images=False)
    assert len(rows) == len(rec["touches"]) > 0
    scene = load_scene(d / "scene.yaml")
    mats = {p.id: p.sim_fabric for p in scene.ordered}
    for row, t in zip(rows, rec["touches"], strict=True):
        assert row["image"]["bytes"] == (d / t["image"]).read_bytes()      # byte for byte
        assert row["no_contact"]["bytes"] == (d / t["no_contact"]).read_bytes()
        assert [x["bytes"] for x in row["extra"]] == [(d / n).read_bytes()
                                                      for n in t.get("extra", [])]
        assert len(row["extra"]) == t["platform_index"]
        assert (row["seq"], row["platform_id"], row["session"]) == (t["seq"], t["platform_id"],
                                                                  session)
        assert ds.features["material"].int2str(row["material"]) == mats[t["platform_id"]]
        assert (row["force_n"], row["depth_m"], row["pose"]) == (t["force_n"], t["depth_m"],
                                                                 t["pose"])
        assert row["prediction"] == rec["result"]["prediction"]
        assert row["correct"] == (mats[row["prediction"]] == mats["reference"])
    n = len(mats)
    followed = [r for r in rows if r["next_platform"] is not None]
    assert len(followed) == len(rec["decisions"])               # one decision per touch after
    assert rows[n - 2]["next_platform"] is None                 # the baseline, the first after
    assert rows[n - 1]["belief"] == pytest.approx(rec["decisions"][0]["belief"])  # touch n


def test_trial_record_round_trip(tmp_path):
    d = _trial(tmp_path / "runs", "t1", SCENE.read_text(), seed=2)
    out = tmp_path / "ds"
    assert main(["export", str(d), "--out", str(out)]) == 0
    ds = _load(out, tmp_path)
    _same_as_record(ds, d)
    card = (out / "README.md").read_text()
    assert card.startswith("---\n") and "infogain" in card and "datasets" in card
    _check_card(out, d, tmp_path)
    decoded = datasets.load_dataset(str(out), split="train", cache_dir=str(tmp_path / "c2"))
    png = cv2.imread(str(d / read_record(d, images=False)["touches"][0]["image"]))
    assert np.array_equal(np.asarray(decoded[0]["image"]), png[:, :, ::-1])   # lossless
    assert main(["export", str(d), "--out", str(out)]) == 2      # not empty: refused


@pytest.mark.slow
def test_session_round_trip(tmp_path):
    sess_file = tmp_path / "s.yaml"
    sess_file.write_text("name: s\ntrials:\n"
                         "  - {id: a, reference: satin, comparisons: [satin, denim, polar_fleece, "
                         "rib_2x2]}\n"
                         "  - {id: b, reference: denim, comparisons: [satin, denim, polar_fleece, "
                         "rib_2x2]}\n")
    ids = [p.id for p in load_scene(SCENE).ordered]
    session = load_session(sess_file, ids, seed=1)
    sd = tmp_path / "session"
    open_session(sd, session, {"scene": str(SCENE)})
    dirs = [_trial(sd, record_name(t.id), placed_scene(SCENE, t.placement), t.seed)
            for t in session.trials]
    out = tmp_path / "ds"
    assert main(["export", str(sd), "--out", str(out)]) == 0
    ds = _load(out, tmp_path)
    for d in dirs:
        _same_as_record(ds, d, session="session")
    assert {r["reference_material"] for r in ds} == {"satin", "denim"}
    out2 = tmp_path / "ds2"                         # a folder of sessions and records
    assert main(["export", str(tmp_path), "--out", str(out2)]) == 0
    assert len(_load(out2, tmp_path)) == len(ds)


def test_library_round_trip_and_bad_input(tmp_path):
    lib = tmp_path / "lib"
    rng = np.random.default_rng(0)
    for c in ("cork", "felt"):
        (lib / c).mkdir(parents=True)
        for i in range(2):
            cv2.imwrite(str(lib / c / f"{i}.png"), rng.integers(0, 255, (240, 320, 3),
                                                                dtype=np.uint8))
    out = tmp_path / "ds"
    assert main(["export", f"replay:{lib}", "--out", str(out)]) == 0
    ds = datasets.load_dataset(str(out), split="train", cache_dir=str(tmp_path / "cache"))
    src = open_source(f"replay:{lib}")
    assert ds.features["material"].names == ["cork", "felt"]
    assert [r["material"] for r in ds] == [0, 0, 1, 1]
    meta = yaml.safe_load((out / "README.md").read_text().split("---\n")[1])
    assert meta["license"] == "other"                  # someone else's presses: theirs
    for row in ds:
        frame = src.touch(lib / row["source_file"]).frame
        assert np.array_equal(np.asarray(row["image"]), frame)
    assert main(["export", str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2
    (tmp_path / "empty").mkdir()
    assert main(["export", str(tmp_path / "empty"), "--out", str(tmp_path / "y")]) == 2


def _check_card(out: Path, record: Path, tmp: Path) -> None:
    """The card of a record's export: CC BY 4.0, tactex's commit, the dataset_info block of
    the Hub (features with material a ClassLabel, the split's rows and bytes), no path of this
    machine and no host name."""
    import socket

    from tactex_ros.export.hf import DATA_LICENSE
    from tactex_ros.trial.report import run_info
    text = (out / "README.md").read_text()
    meta = yaml.safe_load(text.split("---\n")[1])
    assert meta["license"] == DATA_LICENSE == "cc-by-4.0"
    assert meta["tactex"]["commit"] == (run_info()["commit"] or None)
    info = meta["dataset_info"]
    assert info["config_name"] == meta["configs"][0]["config_name"]
    assert info["config_name"] == "tactex-" + meta["tactex"]["fingerprint"]
    feats = {f["name"]: f for f in info["features"]}
    scene = load_scene(record / "scene.yaml")
    names = sorted({p.sim_fabric for p in scene.ordered})
    assert list(feats["material"]["dtype"]["class_label"]["names"].values()) == names
    rows = len(read_record(record, images=False)["touches"])
    assert info["splits"] == [{"name": "train", "num_bytes": info["dataset_size"],
                               "num_examples": rows}]
    assert info["download_size"] == (out / "data" / "train-00000-of-00001.parquet").stat().st_size
    for machine in (str(tmp), str(record.parent), str(config_dir()), str(Path.home()),
                    os.getcwd()):
        assert machine not in text, machine
    cfg = json.loads((record / "config.json").read_text())
    host = (cfg.get("run") or {}).get("host") or socket.gethostname()
    assert f'"{host}"' not in text and '"host"' not in text


def test_two_exports_in_folders_of_one_name_load_each_its_own(tmp_path):
    """``datasets`` caches a local folder by its name and config: each export's config is
    named after its data, so the second never comes back as the first (one cache)."""
    images = {}
    for name, level in (("a", 40), ("b", 200)):
        lib = tmp_path / f"lib_{name}"
        for c in ("cork", "felt"):
            (lib / c).mkdir(parents=True)
            cv2.imwrite(str(lib / c / "0.png"), np.full((240, 320, 3), level, np.uint8))
        assert main(["export", f"replay:{lib}", "--out", str(tmp_path / name / "ds")]) == 0
        images[name] = level
    for name, level in images.items():
        ds = datasets.load_dataset(str(tmp_path / name / "ds"), split="train",
                                   cache_dir=str(tmp_path / "cache"))
        assert np.asarray(ds[0]["image"]).mean() == level, name


def test_machine_paths_are_cut_and_ros_names_kept():
    from tactex_ros.export.hf import _public
    home = str(Path.home())
    assert _public({"host": "lab-pc", "scene_file": f"{home}/ws/scene.yaml",
                    "source": "replay:/tmp/x/octopi-dev", "state_topic": "/tactex/state",
                    "command": "tactex trial --json ~/out/t.json --seed 0"}) == {
        "scene_file": "scene.yaml", "source": "replay:octopi-dev",
        "state_topic": "/tactex/state", "command": "tactex trial --json t.json --seed 0"}


def test_the_command_line_starts_without_datasets():
    code = ("import sys; from tactex_ros.cli.main import build_parser; build_parser(); "
            "build_parser('export'); print(sorted({'datasets', 'pyarrow', 'gymnasium'} & "
            "set(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=dict(os.environ))
    assert out.stdout.strip() == "[]"
