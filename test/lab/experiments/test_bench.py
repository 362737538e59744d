"""Benchmarks run end to end on tiny settings; their JSON has the documented shape."""

import json

from tactex_ros.cli.main import main


def test_bench_latency_json_shape(tmp_path, monkeypatch):
    from tactex_ros.core import config
    # keep the seed-faithful configuration by name, but tiny, so the test is quick
    monkeypatch.setitem(config.PRESETS, "seed_faithful",
                        {**config.PRESETS["seed_faithful"], "input_size": 64, "epochs": 4})
    out = tmp_path / "lat.json"
    assert main(["bench", "latency", "--touches", "5", "7", "--repeats", "2",
                 "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert set(d) == {"seed_faithful", "cnn", "default", "add_touch_median_s", "p99_s",
                      "train_s", "score_s"}
    for name in ("seed_faithful", "cnn", "default"):
        assert set(d[name]) == {"5", "7"} and all(v > 0 for v in d[name].values())
        assert all(d["p99_s"][name][k] >= d[name][k] for k in ("5", "7"))
    assert set(d["add_touch_median_s"]) == {"seed_faithful", "cnn", "default"}


def test_bench_latency_takes_labelled_configs_with_overrides(tmp_path):
    out = tmp_path / "lat.json"
    assert main(["bench", "latency", "--touches", "5", "--repeats", "3", "--configs",
                 "default", "hot=default:learner.match_temperature=0.2", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert set(d["p99_s"]) == {"default", "hot"} and d["hot"]["5"] > 0
    assert main(["bench", "latency", "--configs", "x=nope"]) == 2


def test_bench_sim_json(tmp_path):
    out = tmp_path / "sim.json"
    assert main(["bench", "sim", "--frames", "20", "--repeats", "2", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["fps_median"] > 0 and len(d["fps_runs"]) == 2
