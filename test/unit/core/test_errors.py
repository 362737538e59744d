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


def test_run_time_states_are_not_bad_input():
    """A refused touch and a press cut off are run-time states (exit 1), never InputError."""
    from tactex_ros.core.engine import TouchRejected
    from tactex_ros.core.errors import DeviceError, DeviceNotReady
    from tactex_ros.trial.run import TouchInterrupted
    for cls in (TouchRejected, TouchInterrupted, DeviceNotReady):
        assert issubclass(cls, TrialError) and not issubclass(cls, InputError)
    assert issubclass(DeviceNotReady, DeviceError)


def test_a_spoiled_frame_is_rejected_recorded_and_touched_again():
    """A constant frame from the touch function is refused as the guard refuses (told to
    ``on_rejected`` as TouchRejected), recorded and touched again; a bad platform index given
    to ``add_touch`` stays bad input."""
    import numpy as np

    from tactex_ros.core.engine import TouchRejected
    src = sources.open_source("sim:0.5")
    comps = src.draw_scene(2, 1)
    good = src.trial([comps[0]] + comps, 1)
    calls, seen = {"n": 0}, []

    def touch(p):
        calls["n"] += 1
        return np.full((240, 320, 3), 90, np.uint8) if calls["n"] == 2 else good(p)
    eng = TrialEngine(2, preset("default"), seed=0)
    res = eng.run(touch, on_rejected=lambda p, exc: seen.append((p, exc)))
    assert len(seen) == 1 and isinstance(seen[0][1], TouchRejected)
    assert "constant" in str(seen[0][1]) and res.failed_touches[0]["platform"] == \
        eng.platform_ids[seen[0][0]]
    with pytest.raises(InputError, match="outside"):
        eng.add_touch(7, good(0))
