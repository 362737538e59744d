"""Bad input and run-time failures are two errors with two exit statuses: a trial whose touches
all fail ends with TrialError (exit 1), a bad option with InputError (exit 2)."""

from __future__ import annotations

import pytest

import tactex_ros.sources as sources
from tactex_ros.cli.main import main
from tactex_ros.core.config import preset
from tactex_ros.core.engine import TouchFailed, TrialEngine
from tactex_ros.core.errors import InputError, TrialError


def _failing(platform: int):
    raise TouchFailed("no contact")


def test_the_two_errors_are_distinct():
    assert not issubclass(TrialError, InputError) and not issubclass(InputError, TrialError)


def test_a_trial_whose_touches_all_fail_is_a_trial_error():
    eng = TrialEngine(2, preset("default"), seed=0)
    with pytest.raises(TrialError, match="baseline touches failed"):
        eng.run(_failing)
    assert len(eng.failed) > 0 and eng.failed[0]["reason"] == "no contact"
    with pytest.raises(TrialError, match="decide"):
        eng.decide()


def test_command_line_exits_1_for_a_run_time_failure_and_2_for_bad_input(monkeypatch):
    real = sources.open_source

    class Failing:
        def __init__(self, src):
            self.src = src

        def __getattr__(self, name):
            return getattr(self.src, name)

        def trial(self, classes, seed):
            return _failing

    monkeypatch.setattr(sources, "open_source", lambda spec: Failing(real(spec)))
    assert main(["trial", "--source", "sim", "--quiet"]) == 1
    assert main(["trial", "--source", "sim", "--strategy", "nope", "--quiet"]) == 2
