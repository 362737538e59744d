"""The one job runner: a tiny sweep gives the same results in this process, on joblib worker
processes and on a local Ray instance; bad runner options are refused by name."""

import argparse
import os

import pytest

from tactex_ros.core.config import SHIPPED_STOP, TrialConfig
from tactex_ros.core.errors import InputError
from tactex_lab.experiments.runner import (Backend, TrialJob, add_runner_args, backend_of,
                                           run_jobs, run_parallel)

# descriptor trials: a few hundred ms each, so the sweep costs little beyond starting workers
JOBS = [TrialJob(source="sim", seed=s, preset="default",
                 trial=TrialConfig(strategy=st, rounds=2, stop_confidence=0.0), comparisons=3,
                 trial_id=f"{st}{s}")
        for s in (0, 1) for st in ("infogain", "random")]


def _outcome(res) -> dict:
    """Everything a trial decided (no timings); platforms as indices."""
    return {"trial": res.job.trial_id, "classes": res.classes, "truth": res.truth,
            "prediction": res.prediction, "touches": res.touches,
            "rounds": [(r.platform, r.touches, r.probs) for r in res.decisions[:-1]],
            "final": (res.decisions[-1].touches, res.decisions[-1].probs)}


@pytest.fixture(scope="module")
def in_process():
    return [_outcome(r) for r in run_jobs(JOBS, Backend("joblib", 1), quiet=True)]


def _pid(_: int) -> int:
    return os.getpid()


def test_joblib_workers_give_the_in_process_results(in_process):
    res = run_jobs(JOBS, Backend("joblib", 2), quiet=True)
    assert [_outcome(r) for r in res] == in_process
    # they ran in worker processes, not here
    assert os.getpid() not in run_parallel(_pid, range(4), Backend("joblib", 2), quiet=True)
    assert [r.job.trial_id for r in res] == ["infogain0", "random0", "infogain1", "random1"]


@pytest.mark.soak      # a Ray cluster's start-up is over a minute here: `make test-soak`
def test_a_local_ray_instance_gives_the_joblib_results(in_process):
    ray = pytest.importorskip("ray", reason="ray is not installed")
    try:
        ray.init(num_cpus=2, object_store_memory=80 * 1024 ** 2, include_dashboard=False,
                 log_to_driver=False)
    except Exception as exc:  # noqa: BLE001 - any failure to start Ray here is a skip reason
        pytest.skip(f"a local Ray instance cannot start here: {exc}")
    try:
        res = run_jobs(JOBS, Backend("ray", 2), quiet=True)
    finally:
        ray.shutdown()
    assert [_outcome(r) for r in res] == in_process


def test_run_parallel_keeps_item_order_in_process():
    assert run_parallel(abs, [-3, 1, -2], Backend("joblib", 1), quiet=True) == [3, 1, 2]


def test_runner_options_and_bad_backends():
    p = argparse.ArgumentParser()
    add_runner_args(p)
    b = backend_of(p.parse_args(["--backend", "ray", "--address", "auto", "--workers", "3"]))
    assert b == Backend("ray", 3, "auto")
    assert backend_of(p.parse_args([])) == Backend("joblib", 0, None)
    assert Backend("joblib", 0).resolved().workers >= 1
    assert Backend("ray", 0).resolved().workers == 0          # every CPU of the cluster
    with pytest.raises(InputError, match="--backend 'dask'"):
        Backend("dask")
    with pytest.raises(InputError, match="--workers"):
        Backend("joblib", -1)
    with pytest.raises(InputError, match="--address"):
        Backend("joblib", 2, "auto")


def test_a_result_names_platforms_only_in_its_file_form():
    """The runner's result carries platform indices; ``to_dict`` (files) names them."""
    res = run_jobs(JOBS[:1], Backend("joblib", 1), quiet=True)[0]
    d = res.to_dict()
    assert d["prediction_index"] == res.prediction and d["truth_index"] == res.truth
    assert d["prediction"] == ["reference", "c1", "c2", "c3"][res.prediction]
    chosen = [r.platform for r in res.decisions[:-1]]
    assert all(isinstance(p, int) for p in chosen)
    assert [r["platform"] for r in d["rounds"]] == [["reference", "c1", "c2", "c3"][p]
                                                    for p in chosen]


def test_a_failed_trial_keeps_its_error_and_no_outcome():
    """Every touch blank: the baseline fails; the result says why, has no outcome, and its
    file form names the true platform and no final decision."""
    job = TrialJob(source="sim", seed=0, preset="default",
                   trial=TrialConfig(strategy="infogain", rounds=2, stop_confidence=0.0),
                   comparisons=3, perturb={"blank": 1.0}, catch_errors=True)
    res = run_jobs([job], Backend("joblib", 1), quiet=True)[0]
    assert res.outcome is None and res.prediction is None and not res.correct
    assert res.error and res.failed_touches and res.decisions == []
    d = res.to_dict()
    assert d["final"] is None and d["truth"] == ["reference", "c1", "c2", "c3"][res.truth]


def test_a_job_carries_the_products_trial_settings_and_writes_its_old_file_form():
    """A job's trial settings are the product's ``TrialConfig`` (its defaults: the shipped
    method); the file form names the four trial fields in their old place, and another trial
    setting only when it is not the default."""
    job = TrialJob(source="sim", seed=3, trial=TrialConfig(rounds=7), preset="default")
    d = job.to_dict()
    assert list(d) == ["source", "seed", "strategy", "rounds", "max_touches", "stop_confidence",
                       "preset", "overrides", "platform_classes", "comparisons", "trial_id",
                       "perturb", "tags", "catch_errors", "no_contact_reference"]
    assert (d["strategy"], d["rounds"], d["max_touches"], d["stop_confidence"]) == \
        ("infogain", 7, 0, SHIPPED_STOP)
    sep = TrialJob(source="sim", seed=3, preset="default",
                   trial=TrialConfig(rounds=7, stop_separation=2.0, touch_retries=0)).to_dict()
    assert list(sep)[6:8] == ["stop_separation", "touch_retries"]
    assert (sep["stop_separation"], sep["touch_retries"]) == (2.0, 0)
    job.tags["x"] = 1                       # the file form is a copy
    assert d["tags"] == {}
