"""``tactex experiment stability-real``: break points by hand, and a tiny run end to end on two
replayed octopi-dev scenes (skipped where the recordings are absent)."""

import json

import pytest

from tactex_ros.cli.main import main
from tactex_lab.experiments.stability_real import block, breaks_at


def _runs(correct: list[bool]) -> list[dict]:
    return [{"scene": i, "correct": c, "touches": 2, "rejected": 0, "error": None}
            for i, c in enumerate(correct)]


def test_breaks_at_the_first_significant_drop():
    clean = block(_runs([True] * 8), None)
    levels = {"1": block(_runs([True] * 6 + [False] * 2), _runs([True] * 8)),   # p = 0.5
              "2": block(_runs([True] * 2 + [False] * 6), _runs([True] * 8)),   # p = 0.031
              "4": block(_runs([False] * 8), _runs([True] * 8))}
    assert levels["2"]["mcnemar_vs_clean"]["p"] == pytest.approx(2 * 0.5 ** 6)
    assert breaks_at([1.0, 2.0, 4.0], levels, clean, 0.05) == 2.0
    assert breaks_at([1.0], levels, clean, 0.05) is None
    assert levels["1"]["accuracy"] == 0.75 and levels["1"]["ci95"][0] < 0.75


@pytest.mark.slow
def test_stability_real_end_to_end(octopi_dir, tmp_path):
    out = tmp_path / "sr"
    args = ["experiment", "stability-real", "--source", f"replay:{octopi_dir}",
            "--methods", "default", "--perturbations", "partial", "low_force", "--scenes", "2",
            "--budget", "2", "--workers", "1", "--quiet", "--guard", "partial",
            "--guard-set", "learner.contact_region_min=0.6", "--out", str(out)]
    assert main(args) == 0
    s = json.loads((out / "summary.json").read_text())
    t = s["table"]["default"]
    assert t["clean"]["n"] == 2 and set(t) == {"clean", "partial", "low_force"}
    assert list(t["partial"]["levels"]) == ["0.25", "0.5", "0.75", "0.9"]
    assert all(b["n"] == 2 and b["ci95"][0] <= b["accuracy"] <= b["ci95"][1]
               for b in t["partial"]["levels"].values())
    assert [r["severity"] for r in s["guard"]["per_severity"]] == [0.25, 0.5, 0.75, 0.9]
    assert (out / "severity.png").stat().st_size > 0
    runs = json.loads((out / "runs.json").read_text())
    assert len(runs) == 2 * (1 + 4 + 4) + 2 * (1 + 4)
    # --reuse: nothing left to run, the same summary
    again = tmp_path / "again"
    assert main(args[:-1] + [str(again), "--reuse", str(out)]) == 0
    s2 = json.loads((again / "summary.json").read_text())
    assert s2["run_here"] == 0 and s2["table"] == s["table"]
    # bad input: named, exit 2
    assert main(args[:-1] + [str(tmp_path / "x"), "--perturbations", "rain"]) == 2
    assert main(args[:-1] + [str(tmp_path / "y"), "--reuse", str(tmp_path)]) == 2
