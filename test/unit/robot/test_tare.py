"""The tare before each descent (pure, no rclpy): a wrench offset (payload, model error) is
measured at the approach point at rest and removed, so threshold and limit act on the contact
force; a tare that does not settle, or an offset too large, refuses the press with that reason;
the tare is in the outcome."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tactex_ros.core.paths import config_dir
from tactex_ros.robot.mock_world import ArmModel, ControlLaw
from tactex_ros.robot.press import DESCEND, PressController, Tare, TareResult, tared
from tactex_ros.robot.scene import load_scene


def _scene(**press):
    sc = load_scene(config_dir() / "scene_sim.yaml")
    return replace(sc, press=sc.press.replace(**press)) if press else sc


def _press(scene, *, offset: float = 0.0, noise: float = 0.0, drift: float = 0.0,
           seed: int = 0, rate_hz: float = 100.0, t_max: float = 90.0):
    """Closed loop against the mock arm; the wrench read is contact + ``offset`` + gaussian
    ``noise`` (std) + ``drift`` * t [N]. Returns (outcome, contact force per tick, controller,
    the contact force when the descent ended)."""
    rng = np.random.default_rng(seed)
    arm = ArmModel(scene, np.array([0.5, 0.0, 0.3]), ControlLaw(stiffness=1000.0))
    ctrl = PressController(scene, scene.platform("c3"), arm.position, 0.0, stiffness=1000.0)
    t, dt, contact, at_stop = 0.0, 1.0 / rate_hz, [], None
    while not ctrl.done and t < t_max:
        read = arm.normal_force() + offset + noise * rng.standard_normal() + drift * t
        phase = ctrl.phase
        arm.target = ctrl.step(t, arm.position, read)
        if phase == DESCEND and ctrl.phase != DESCEND:
            at_stop = arm.normal_force()
        if ctrl.capture_requested:
            ctrl.captured(True, "", t)
        arm.step(dt)
        contact.append(arm.peak_force)
        t += dt
    return ctrl.outcome(), np.array(contact), ctrl, at_stop


@pytest.mark.parametrize("offset", [3.0, -3.0, 0.0])
def test_offset_is_removed_so_threshold_and_limit_act_on_the_contact(offset: float) -> None:
    scene = _scene()
    s = scene.press
    out, contact, _, at_stop = _press(scene, offset=offset, noise=0.05)
    assert out.success, out.reason
    assert out.tare is not None and out.tare.samples >= 3
    assert out.tare.offset_n == pytest.approx(offset, abs=0.1)
    assert out.tare.spread_n <= s.tare_max_spread_n
    # the descent stopped at the threshold of *contact* force (untared: at threshold - offset)
    assert at_stop == pytest.approx(s.force_threshold, abs=0.6)
    assert out.force_n == pytest.approx(s.force_threshold, rel=0.15)
    assert contact.max() < s.max_force


def test_noisy_wrench_does_not_settle_and_refuses_the_press() -> None:
    scene = _scene()
    out, contact, ctrl, _ = _press(scene, noise=1.5)
    assert not out.success and out.reason.startswith("tare did not settle")
    assert out.tare is None
    assert contact.max() == 0.0          # never descended onto the platform


def test_drifting_wrench_does_not_settle() -> None:
    out, _, _, _ = _press(_scene(tare_max_spread_n=0.2), drift=2.0)   # 2 N/s
    assert not out.success and out.reason.startswith("tare did not settle")


def test_offset_above_the_limit_refuses_the_press() -> None:
    scene = _scene()
    out, contact, _, _ = _press(scene, offset=scene.press.tare_max_offset_n + 1.0)
    assert not out.success and out.reason.startswith("tare: offset")
    assert contact.max() == 0.0


def test_tare_median_ignores_an_outlier_and_needs_a_full_quiet_window() -> None:
    tare = Tare(window_s=0.3, max_spread_n=0.5, max_motion_m=0.001)
    x = np.zeros(3)
    for i in range(9):                         # 0.0 .. 0.24 s: not yet 90 % of the window
        tare.add(i * 0.03, 1.0 + (5.0 if i == 4 else 0.0), x)
    assert tare.settled() is None
    tare.add(0.27, 1.0, x)
    tare.add(0.3, 1.0, x)
    got = tare.settled()
    assert isinstance(got, TareResult) and got.offset_n == pytest.approx(1.0)
    assert got.samples == 11
    moving = Tare(window_s=0.3, max_spread_n=0.5, max_motion_m=0.001)
    for i in range(11):
        moving.add(i * 0.03, 1.0, np.array([0.0, 0.0, 0.0005 * i]))
    assert moving.settled() is None and moving.last.motion_m == pytest.approx(0.005)


def test_tared_keeps_the_lateral_part() -> None:
    fn, mag = tared(5.0, 5.0, 2.0)
    assert (fn, mag) == (3.0, 3.0)
    fn, mag = tared(4.0, 5.0, 1.0)            # lateral 3 N
    assert fn == 3.0 and mag == pytest.approx(np.hypot(3.0, 3.0))
