"""Accuracy charts (issue 23): Wilson bands per point, the trial-time axis, pooling run JSONs
of several seeds, and the ``experiment accuracy-charts`` command's files and refusals."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tactex_lab.analysis import charts
from tactex_lab.experiments import accuracy_charts
from tactex_lab.experiments.protocol import band_rows
from tactex_ros.core.errors import InputError


def _wilson(s: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    p = s / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return mid - half, mid + half


def test_band_series_exact_wilson():
    right = np.array([[1, 1], [1, 0], [0, 0], [1, 1]], dtype=bool)
    b = charts.band_series(right, [0, 1])
    assert b["n"] == 4 and b["x"] == [0.0, 1.0] and b["accuracy"] == [0.75, 0.5]
    np.testing.assert_allclose(b["lo"], [0.30064184258240184, 0.15003898915214953], atol=1e-12)
    np.testing.assert_allclose(b["hi"], [0.9544127391902995, 0.8499610108478505], atol=1e-12)
    for k, s in enumerate((3, 2)):
        np.testing.assert_allclose((b["lo"][k], b["hi"][k]), _wilson(s, 4), atol=1e-9)
    with pytest.raises(ValueError):
        charts.band_series(right, [0, 1, 2])


def test_trial_time_counts_baseline_presses_and_decisions():
    assert charts.trial_time([0, 1, 2], 5, 15.5, 0.01) == pytest.approx([77.51, 93.02, 108.53])


def _curve(extra, correct):
    """A belief curve's JSON form, as runs.json holds it."""
    return {"extra": extra, "correct": correct, "conf": [0.5] * len(extra),
            "decision_s": [0.01] * len(extra)}


def _folder(tmp: Path, name: str, runs: dict, budget: int = 3) -> Path:
    d = tmp / name
    d.mkdir()
    (d / "runs.json").write_text(json.dumps(runs))
    (d / "summary.json").write_text(json.dumps({"budget": budget, "comparisons": 4}))
    return d


def test_right_after_and_pooling_two_seeds(tmp_path):
    c = _curve([0, 1, 3], [False, True, True])
    a = _folder(tmp_path, "s0", {"default": [c], "whiten": [_curve([0], [True])]})
    b = _folder(tmp_path, "s1", {"default": [_curve([0, 2], [True, False])] * 2})
    curves, budget, comparisons = accuracy_charts.load_runs([a, b])
    assert (budget, comparisons) == (3, 4) and list(curves) == ["default", "whiten"]
    rows = band_rows(curves, budget)
    right, dec = rows["default"]
    assert right.shape == (3, 4) and dec == 0.01
    # right after k = 0..3: [F, T, T, T] once, [T, F, F, F] twice (the last decision holds)
    assert right.tolist() == [[False, True, True, True]] + [[True, False, False, False]] * 2
    assert rows["whiten"][0].shape == (1, 4)
    with pytest.raises(InputError):
        accuracy_charts.load_runs([a], ["nope"])
    with pytest.raises(InputError):
        accuracy_charts.load_runs([a, _folder(tmp_path, "s2", {}, budget=5)])


def _bench(tmp: Path, seconds: float = 2.76) -> Path:
    """A `tactex bench press --json` result (the fields press_time reads)."""
    f = tmp / "bench.json"
    f.write_text(json.dumps({"scene": "/x/config/scene.yaml", "worlds": 1000,
                             "press_s_median": seconds}))
    return f


def _record(root: Path, name: str, times: list[tuple[float, float]]) -> Path:
    d = root / name
    d.mkdir(parents=True)
    (d / "touches.jsonl").write_text("".join(
        json.dumps({"seq": i, "platform": "c1", "requested": a, "stamp": b}) + "\n"
        for i, (a, b) in enumerate(times)))
    return d


def test_press_time_from_the_bench_and_from_recorded_presses(tmp_path):
    from tactex_lab.experiments.protocol import DEFAULT_PRESS_TIME, press_time
    got = press_time(_bench(tmp_path, 2.5))
    assert got.seconds == 2.5 and got.note == "bench press, scene.yaml"
    # a session folder: every recorded press of every trial below it (a press never captured
    # has no stamp and is left out)
    _record(tmp_path / "s", "t1", [(10.0, 12.0), (20.0, 23.0)])
    _record(tmp_path / "s", "t2", [(5.0, 9.0)])
    (tmp_path / "s" / "t2" / "touches.jsonl").open("a").write(
        json.dumps({"seq": 9, "requested": 30.0}) + "\n")
    got = press_time(tmp_path / "s")
    assert got.seconds == 3.0 and got.note == "3 recorded presses"
    # the default: the benchmark of the lab scene as shipped
    assert press_time().seconds == json.loads(DEFAULT_PRESS_TIME.read_text())["press_s_median"]
    for bad in (tmp_path / "none", _bench(tmp_path, 0.0), tmp_path / "empty"):
        (tmp_path / "empty").mkdir(exist_ok=True)
        with pytest.raises(InputError, match="--press-time"):
            press_time(bad)


@pytest.mark.slow
def test_command_writes_both_charts_and_refuses_bad_input(tmp_path):
    from tactex_ros.cli.main import main
    a = _folder(tmp_path, "s0", {"default": [_curve([0, 1, 3], [False, True, True])] * 3})
    out = tmp_path / "charts"
    bench = str(_bench(tmp_path))
    assert main(["experiment", "accuracy-charts", "--runs", str(a), "--press-time", bench,
                 "--out", str(out)]) == 0
    for name in ("accuracy_vs_touches.png", "accuracy_vs_time.png"):
        assert (out / name).stat().st_size > 1000
    pooled = json.loads((out / "pooled.json").read_text())
    assert pooled["scenes"] == {"default": 3}
    assert pooled["press_time"]["seconds"] == 2.76
    # right after k = 0..3: wrong at the baseline, right from the first touch on
    assert pooled["right_after"] == {"default": {"n": 3, "right": [0, 3, 3, 3],
                                                 "decision_s_median": 0.01}}
    at_09 = [r for r in pooled["report_rows"] if r["theta"] == 0.9][0]
    # belief 0.5 never reaches 0.9: each scene ends at its last decision (3 touches, right)
    assert (at_09["accuracy"], at_09["touches"], at_09["wrong_stop"]) == (1.0, 3.0, 0.0)
    # redrawn from its counts alone (no runs.json): the same bands
    only = tmp_path / "only"
    only.mkdir()
    (only / "pooled.json").write_text((out / "pooled.json").read_text())
    assert main(["experiment", "accuracy-charts", "--runs", str(only), "--press-time", bench,
                 "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "accuracy_vs_time.png").stat().st_size > 1000
    assert main(["experiment", "accuracy-charts", "--runs", str(a), "--press-time", bench,
                 "--paired-against", "nope", "--out", str(out)]) == 2
    assert main(["experiment", "accuracy-charts", "--runs", str(tmp_path / "none"),
                 "--press-time", bench, "--out", str(out)]) == 2
    assert main(["experiment", "accuracy-charts", "--runs", str(a), "--press-time",
                 str(tmp_path / "no_bench.json"), "--out", str(out)]) == 2
    assert main(["experiment", "accuracy-charts", "--runs", str(a), "--press-time", bench,
                 "--per-class", "1.5", "--out", str(out)]) == 2


def test_counts_from_a_summary_give_the_bands_of_the_runs():
    counts = accuracy_charts.rows_from_counts(
        {"right_after": {"d": {"n": 4, "right": [3, 2], "decision_s_median": 0.02}}})
    right, dec = counts["d"]
    b = charts.band_series(right, [0, 1])
    assert dec == 0.02 and b["n"] == 4 and b["accuracy"] == [0.75, 0.5]
    np.testing.assert_allclose(b["lo"], [0.30064184258240184, 0.15003898915214953], atol=1e-12)
    with pytest.raises(InputError):
        accuracy_charts.rows_from_counts({"right_after": {"d": {"n": 2, "right": [3],
                                                                "decision_s_median": 0}}})


def test_outcome_per_reference_class_at_the_stop():
    from tactex_lab.experiments.curves import BeliefCurve
    from tactex_lab.experiments.protocol import per_class

    def c(ref: str, correct: list[bool], conf: list[float]) -> BeliefCurve:
        n = len(correct)
        return BeliefCurve(tuple(range(n)), tuple(correct), tuple(conf), (0.01,) * n,
                           classes=(ref, "x", "y", "z", "w"))
    cs = [c("a", [False, True], [0.95, 0.99]),     # stops sure and wrong at 0
          c("a", [True, True], [0.5, 0.92]),       # stops right at 1
          c("b", [True, False], [0.5, 0.6]),       # never sure: wrong at its last decision
          c("b", [True], [0.91]),
          c("b", [True], [0.91]),
          BeliefCurve((0,), (False,), (0.99,), (0.01,))]   # no classes: left out
    rows = per_class(cs, 0.9)
    assert rows == [
        {"class": "a", "scenes": 2, "wrong": 1, "wrong_stops": 1, "touches": 0.5},
        {"class": "b", "scenes": 3, "wrong": 1, "wrong_stops": 0, "touches": 1 / 3}]
    # at 0.96 the first scene goes on and ends right: class a drops below b
    assert [(r["class"], r["wrong"], r["touches"]) for r in per_class(cs, 0.96)] == [
        ("b", 1, 1 / 3), ("a", 0, 1.0)]
