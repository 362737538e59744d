"""The press under Cartesian impedance control against the spring-damper mock arm (pure, no
rclpy): threshold reached and held, no contact, sign and force aborts, deadlines, and the force
limit held at every sample of the mock over controller and platform stiffnesses."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tactex_ros.core.errors import TactexError
from tactex_ros.robot.press import (DONE, SETTLE, ArmModel, PressController, check_press,
                                   equilibrium_floor, platform_under)
from tactex_ros.paths import config_dir
from tactex_ros.robot.scene import load_scene


def _scene(name: str = "scene_sim.yaml", **press):
    sc = load_scene(config_dir() / name)
    return replace(sc, press=sc.press.replace(**press)) if press else sc


def _simulate(scene, platform_id: str, *, stiffness: float = 1000.0,
              platform_stiffness: float = 2e4, mass: float = 3.0, platform_damping: float = 50.0,
              target_filter_s: float = 0.0, surface_offset: float = 0.0, rate_hz: float = 50.0,
              capture_ok: bool = True, force_sign: float = 1.0, t_max: float = 90.0):
    """Closed loop at ``rate_hz``: controller -> mock arm (1 ms substeps) -> controller.

    Returns (outcome, positions per tick, the mock's peak force per tick, targets, controller,
    normal force at each tick)."""
    arm_scene = scene
    if surface_offset:
        arm_scene = replace(scene, platforms=tuple(
            p.replace(position=(p.position[0], p.position[1], p.position[2] + surface_offset))
            for p in scene.platforms))
    arm = ArmModel(arm_scene, np.array([0.5, 0.0, 0.3]), stiffness=stiffness, mass=mass,
                   platform_stiffness=platform_stiffness, platform_damping=platform_damping,
                   target_filter_s=target_filter_s, substep=1e-3)
    ctrl = PressController(scene, scene.platform(platform_id), arm.position, 0.0,
                           stiffness=stiffness)
    t, dt = 0.0, 1.0 / rate_hz
    pos, peaks, targets, forces = [], [], [], []
    while not ctrl.done and t < t_max:
        f = force_sign * arm.normal_force()
        arm.target = ctrl.step(t, arm.position, f)
        targets.append(arm.target.copy())
        forces.append(f)
        if ctrl.capture_requested:
            ctrl.captured(capture_ok, "" if capture_ok else "no frame", t)
        arm.step(dt)
        pos.append(arm.position.copy())
        peaks.append(arm.peak_force)
        t += dt
    return (ctrl.outcome(), np.array(pos), np.array(peaks), np.array(targets), ctrl,
            np.array(forces))


def test_press_reaches_threshold_holds_it_and_retracts() -> None:
    scene = _scene()
    s = scene.press
    out, pos, peaks, targets, ctrl, forces = _simulate(scene, "c3")
    assert out.success and ctrl.phase == DONE
    assert s.force_threshold * 0.9 <= out.force_n < s.max_force
    assert peaks.max() < s.max_force
    # the equilibrium went below the surface (impedance control), the sensor far less
    surface = scene.platform("c3").position[2]
    assert targets[:, 2].min() < surface - s.force_threshold / 1000.0 * 0.9
    assert surface - pos[:, 2].min() < s.max_depth
    # commanded speed never above max_speed (per 20 ms tick)
    steps = np.linalg.norm(np.diff(targets, axis=0), axis=1)
    assert steps.max() <= s.max_speed * 0.02 + 1e-9
    assert np.all(targets >= np.array(scene.workspace_min) - 1e-9)
    assert np.all(targets <= np.array(scene.workspace_max) + 1e-9)
    np.testing.assert_allclose(pos[-1], np.array(scene.platform("c3").position) +
                               [0, 0, s.approach_height], atol=s.position_tolerance)


def test_contact_is_held_during_settle_and_capture() -> None:
    """The old press set the target to the measured pose at the threshold: under impedance
    control that releases the contact. Now the force stays near the threshold while held."""
    scene = _scene()
    arm = ArmModel(scene, np.array([0.5, 0.0, 0.3]), stiffness=300.0, substep=1e-3)
    ctrl = PressController(scene, scene.platform("c2"), arm.position, 0.0, stiffness=300.0)
    t, held = 0.0, []
    while not ctrl.done and t < 60:
        arm.target = ctrl.step(t, arm.position, arm.normal_force())
        if ctrl.phase == SETTLE:
            held.append(arm.normal_force())
        if ctrl.capture_requested:
            ctrl.captured(True, "", t)
        arm.step(0.02)
        t += 0.02
    assert ctrl.outcome().success
    held = np.array(held[len(held) // 2:])     # second half of settle
    assert held.min() > 0.8 * scene.press.force_threshold
    assert held.max() < 1.2 * scene.press.force_threshold


def test_equilibrium_floor_and_reachability() -> None:
    s = _scene().press
    assert equilibrium_floor(s, 1e5) == s.max_depth
    assert equilibrium_floor(s, 150.0) == pytest.approx(0.5 * (s.force_threshold + s.max_force)
                                                        / 150.0)
    check_press(_scene(), 150.0)
    with pytest.raises(TactexError, match="descend_deadline_s"):
        check_press(_scene(descend_deadline_s=3.0), 150.0)
    with pytest.raises(TactexError, match=r"platforms\[0\].*workspace.min"):
        check_press(_scene(), 20.0)


def test_press_without_contact_fails() -> None:
    scene = _scene()
    for k in (300.0, 3000.0):
        out, pos, *_ = _simulate(scene, "c1", stiffness=k, surface_offset=-0.03)
        assert not out.success and out.reason.startswith("no contact"), out.reason
        surface = scene.platform("c1").position[2]
        assert pos[:, 2].min() >= surface - equilibrium_floor(scene.press, k) - 0.002


def test_wrong_force_sign_aborts() -> None:
    out, *_ = _simulate(_scene(), "c2", force_sign=-1.0)
    assert not out.success and out.reason.startswith("force sign")


def test_force_limit_aborts_and_retracts() -> None:
    scene = _scene()
    ctrl = PressController(scene, scene.platform("c2"), np.array([0.38, 0.22, 0.1]), 0.0)
    ctrl.phase = "descend"
    ctrl.step(0.02, np.array([0.38, 0.22, 0.08]), 3.0, force_magnitude=scene.press.max_force + 1)
    assert ctrl.failure.startswith("force limit") and ctrl.phase == "retract"


def test_capture_failure_and_deadline() -> None:
    scene = _scene()
    out, *_ = _simulate(scene, "c2", capture_ok=False)
    assert not out.success and out.reason.startswith("capture failed")
    ctrl = PressController(scene, scene.platform("c4"), np.array([0.5, 0.0, 0.3]), 0.0)
    t = 0.0
    while ctrl.phase == "approach" and t < 100:   # the arm never moves
        ctrl.step(t, np.array([0.5, 0.0, 0.3]), 0.0)
        t += 0.05
    assert ctrl.failure.startswith("deadline")
    assert t <= scene.press.approach_deadline_s + 0.1


@pytest.mark.slow
def test_force_limit_holds_at_every_sample_over_stiffnesses() -> None:
    """Property: for controller stiffness 150-3000 N/m, platform stiffness 2e3-5e4 N/m, mass
    1-5 kg, platform damping 0-100 N s/m, with and without the controller's 0.2 s target
    filter, the mock's contact force stays below max_force at every 1 ms sample, and a press
    either succeeds near the threshold or fails with a named reason."""
    rng = np.random.default_rng(13)
    scene = _scene(descend_speed=0.005, descend_deadline_s=25.0)
    s = scene.press
    results = []
    for i in range(10):
        k = float(np.exp(rng.uniform(np.log(150.0), np.log(3000.0))))
        kp = float(np.exp(rng.uniform(np.log(2e3), np.log(5e4))))
        out, _, peaks, *_ = _simulate(
            scene, ["c1", "c2", "c3", "c4"][i % 4], stiffness=k, platform_stiffness=kp,
            mass=float(rng.uniform(1.0, 5.0)), platform_damping=float(rng.uniform(0.0, 100.0)),
            target_filter_s=0.2 if i % 2 else 0.0)
        assert peaks.max() < s.max_force, (k, kp, peaks.max())
        assert out.success or out.reason, (k, kp)
        if out.success:
            assert 0.5 * s.force_threshold <= out.force_n <= s.max_force
        results.append(out.success)
    assert sum(results) >= 8, results


def test_platform_under_is_the_one_answer_of_mock_arm_and_camera() -> None:
    sc = _scene()
    p1 = sc.platforms[1]
    x, y, z = p1.position
    # inside the disc, 2 mm below the surface; on its rim; just outside it; above it
    assert platform_under(sc.platforms, np.array([x, y, z - 0.002])) == (1, pytest.approx(0.002))
    assert platform_under(sc.platforms, np.array([x + p1.radius, y, z + 0.01])) == (1, 0.0)
    assert platform_under(sc.platforms, np.array([x + p1.radius + 1e-4, y, z]))[0] != 1
    # the mock arm's contact is the same platform and depth
    arm = ArmModel(sc, np.array([x, y, z - 0.002]))
    got, pen = arm.contact()
    assert got is p1 and pen == pytest.approx(0.002)
