"""The press in a simulated world with the faults real arms have (pure, no rclpy): each of the
sensitivity study's effects on its own (issue 28's table: the old press failed or captured at
the wrong force in every row but the first), CRISP 2.3's filters and stiffness clamp, v1.0.0's
activation transient, and a property test over 1000 seeded worlds drawn from the ranges a lab
meets (docs/simulated_world.md). The true contact force is the mock's, not the reading."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tactex_ros.core.paths import config_dir
from tactex_ros.robot import press_bench
from tactex_ros.robot.mock_world import (CRISP_23, ArmModel, ControlLaw, Faults,
                                         press_in_worlds)
from tactex_ros.robot.robots import load_profile
from tactex_ros.robot.scene import load_scene

SIM = load_scene(config_dir() / "scene_sim.yaml")
# the lab scene's forces (config/scene.yaml: force_threshold 5 N, max_force 12 N, max_depth
# 12 mm) at the simulated scene's speeds
LAB = replace(SIM, press=SIM.press.replace(force_threshold=5.0, max_force=12.0))
LAW = ControlLaw(stiffness=1000.0)


def _tolerance(scene) -> float:
    """How close the true contact force at capture must be to the intended force [N]: the
    press's own band plus 0.3 N for the drift of the reading over a press."""
    return scene.press.force_tolerance_n + 0.3


def _one(faults: Faults, scene=LAB, law: ControlLaw = LAW, platform: str = "c2"):
    above = np.asarray(scene.platform(platform).position) + [0.0, 0.0, 0.04]
    (got,) = press_in_worlds(scene, law, [faults], [platform], start=above)
    assert got.peak_force_n < scene.press.max_force, got
    return got


def _captured_at_intended_force(got, scene=LAB) -> None:
    out = got.outcome
    assert out.success, out.reason
    assert abs(got.true_force_n - scene.press.force_threshold) <= _tolerance(scene), got
    assert abs(out.force_n - scene.press.force_threshold) <= scene.press.force_tolerance_n


# ---------------------------------------------------------------------- the six rows

def test_perfect_world() -> None:
    got = _one(Faults())
    _captured_at_intended_force(got)
    assert out_surface_error(got) < 0.0005 and not got.outcome.warning


def out_surface_error(got) -> float:
    return abs(got.outcome.surface_z - got.true_surface_z)


def test_unmodelled_upward_force_is_pushed_through() -> None:
    """2.5 N up (a cable): the tare removes it from the reading; the old hold assumed spring
    force = contact force and captured at 2.70 N; the force feedback reaches 5 N."""
    _captured_at_intended_force(_one(Faults(static_force=(0.0, 0.0, 2.5))))


@pytest.mark.parametrize("static", [(0.0, 0.0, 4.0), (2.5, 0.0, 0.0)])
def test_arm_held_off_its_goal_still_arrives(static) -> None:
    """4 N up or 2.5 N sideways hold the arm 4 mm / 2.5 mm off every goal, more than the 2 mm
    arrival tolerance (the old press ran into the approach deadline): it arrives at rest."""
    _captured_at_intended_force(_one(Faults(static_force=static)))


def test_a_sagging_arm_ends_its_retract_where_it_rests() -> None:
    """3 N down holds the arm 3 mm below every goal, more than the 2 mm arrival tolerance:
    the retract, like the approach, counts the goal reached where the sagging arm rests
    (the travel's sag) instead of waiting rest_s (measured 0.76 s before, 0.24 s after; the
    arm without the force 0.16 s)."""
    scene = load_scene(config_dir() / "scene.yaml")
    got = _one(Faults(static_force=(0.0, 0.0, -3.0)), scene=scene)
    assert got.outcome.success, got.outcome.reason
    assert got.outcome.phase_s["retract"] < 0.4, got.outcome.phase_s
    assert got.outcome.phase_s["retract"] < scene.press.rest_s, got.outcome.phase_s


def test_surface_lower_than_measured_is_found_and_reported() -> None:
    got = _one(Faults(surface_offset=-0.004))
    _captured_at_intended_force(got)
    assert out_surface_error(got) < 0.0005
    assert got.outcome.warning.startswith("surface moved")


def test_fabric_on_foam_reaches_the_force() -> None:
    """1e3 N/m: 5 N needs 5 mm of the platform plus 5 mm of the controller's spring (the old
    press stopped at its floor with 4.3 N)."""
    _captured_at_intended_force(_one(Faults(platform_stiffness=1e3)))


def test_soft_platform_with_friction_and_lift() -> None:
    _captured_at_intended_force(_one(Faults(platform_stiffness=2e3, coulomb_friction=1.5,
                                            static_force=(0.0, 0.0, 1.5))))


def test_softest_platform_within_max_depth_and_beyond_it() -> None:
    """5e2 N/m (fabric on soft foam) needs 10 mm: inside the lab scene's max_depth (12 mm);
    with max_depth 8 mm it is physically out of reach and refused by name."""
    _captured_at_intended_force(_one(Faults(platform_stiffness=5e2)))
    tight = replace(LAB, press=LAB.press.replace(max_depth=0.008))
    got = _one(Faults(platform_stiffness=5e2), scene=tight)
    assert not got.outcome.success and got.outcome.reason.startswith("too soft")


# ---------------------------------------------------------------------- the controller

def test_crisp_23_filters_and_clamp() -> None:
    """CRISP 2.3.x: filters on q, dq and the output torque (0.5) and the stiffness clamped at
    900 N/m with the damping still from 1000; the press assumes 1000 and still holds 5 N."""
    law = load_profile("fr3_crisp").law.replace(**CRISP_23)
    assert law.k == 900.0 and law.d == pytest.approx(2.0 * math.sqrt(1000.0))
    _captured_at_intended_force(_one(Faults(), law=law))
    _captured_at_intended_force(_one(Faults(static_force=(0.0, 0.0, 2.5)), law=law))


def test_stiffness_clamp_is_what_the_arm_feels() -> None:
    law = ControlLaw(stiffness=1000.0, max_stiffness=900.0)
    arm = ArmModel(SIM, np.array([0.0, 2.0, 0.3]), law)
    arm.target = arm.position + [0.0, 0.0, -0.01]
    arm.control()
    assert arm.command[2] == pytest.approx(-9.0)


def test_activation_transient_is_bounded_by_the_error_clip() -> None:
    """v1.0.0 after activation: the filtered target ~92 mm off for a few ms; the error clip
    (10 mm) bounds the push at 10 N, the arm moves a fraction of a millimetre."""
    law = load_profile("fr3_crisp").law.replace(activation_jump=(0.0, 0.054, -0.074),
                                                activation_jump_s=0.005)
    assert np.linalg.norm(law.activation_jump) == pytest.approx(0.0916, abs=1e-3)
    arm = ArmModel(SIM, np.array([0.0, 2.0, 0.3]), law)
    start = arm.position.copy()
    arm.release()
    pushes = []
    for _ in range(200):
        arm.cycle()
        pushes.append(np.abs(arm.command).max())
    assert max(pushes) <= 10.0 + 1e-9 and max(pushes) > 2.0
    assert np.linalg.norm(arm.position - start) < 0.001


# ---------------------------------------------------------------------- 1000 worlds

@pytest.mark.parametrize("scene", ["scene.yaml", "scene_panda.yaml"])
@pytest.mark.parametrize("n", [pytest.param(1000, marks=[pytest.mark.slow, pytest.mark.soak]), 60])
def test_every_press_in_1000_worlds_on_the_shipped_scene(n: int, scene: str) -> None:
    """Property over seeded worlds (``Faults.draw``: offset up to 5 N with drift and a
    configuration part, static force up to 4 N up or down and 3 N sideways, Coulomb friction
    up to 2 N, surface +-5 mm, platforms 5e2-5e4 N/m, noise 0.05-0.3 N, mass 1-5 kg), on the
    shipped scene as shipped and its robot profile's law (``robot.press_bench``: each world
    presses twice, first on the scene's surface, then on the one it found): >= 99 % captured
    within force_tolerance_n of the intended force (true contact force), every other press a
    named refusal, never a success at the wrong force, no control cycle with the true contact
    force over max_force, and the press's time (approach start to lift-off, the travel from the
    platform before included) about 3 s in the median. (1000 worlds: `make test-soak`; the first 60
    run in every test run.)"""
    out = press_bench.run(config_dir() / scene, n, seed=0)
    # measured at 1000 worlds (docs/research/press_speed.md): 0.996 captured, 2.76 s median,
    # 3.67 s p95; 60 worlds are too few for the time's percentiles: a margin there
    assert out["captured_share"] >= (0.99 if n >= 1000 else 0.98), out
    assert out["unnamed_refusals"] == 0 and out["silent_wrong"] == 0, out
    assert out["over_limit_samples"] == 0 and out["peak_force_n"] < 12.0, out
    assert out["press_s_median"] <= (3.0 if n >= 1000 else 3.2), out
    assert out["press_s_p95"] <= (4.0 if n >= 1000 else 4.3), out


@pytest.mark.parametrize("n", [pytest.param(1000, marks=[pytest.mark.slow, pytest.mark.soak]),
                               60])
def test_heavy_arm_with_a_5_mm_approach_never_over_presses(n: int) -> None:
    """Issue 46's silent over-force: a 6 kg apparent mass with a 2-4 N static downward force
    and the approach shortened to 5 mm over a measured scene (surfaces within 2 mm). The approach point is raised by the sag measured on the
    travel, so the arm, not its target, stops above the surface: no true contact force over
    max_force at any control cycle, no success at the wrong force, and the reported
    max_force_n is the largest of every sample. The press takes about 3 s here too: the
    approach arrives where the sagging arm rests, not only at rest."""
    out = press_bench.run(config_dir() / "scene.yaml", n, seed=1, heavy=True,
                          approach_height=0.005, surface_tolerance=0.002)
    assert out["over_limit_samples"] == 0 and out["peak_force_n"] < 12.0, out
    assert out["silent_wrong"] == 0 and out["unnamed_refusals"] == 0, out
    assert out["captured_share"] >= 0.99, out
    # measured at 1000 worlds: 2.82 s median, 3.94 s p95 (was 3.46 / 4.28 s waiting rest_s)
    assert out["press_s_median"] <= (3.0 if n >= 1000 else 3.2), out
    assert out["press_s_p95"] <= (4.0 if n >= 1000 else 4.3), out


def test_press_counter_counts_a_press_once_through_a_dip_and_again_after_a_lift() -> None:
    """A force that dips below the contact threshold while the sensor stays on the surface is
    the same press; a lift of more than ``clear_m`` ends it; moving off the platforms too."""
    from types import SimpleNamespace

    from tactex_ros.robot.mock_world import PressCounter
    plat = [SimpleNamespace(id="c1", position=(0.5, 0.0, 0.1), radius=0.03)]
    c = PressCounter()
    on, below, lifted_a_bit, lifted = ((0.5, 0.0, 0.1), (0.5, 0.0, 0.099), (0.5, 0.0, 0.1005),
                                       (0.5, 0.0, 0.102))
    steps = [(lifted, 0.0), (below, 0.0), (below, 2.0), (below, 0.01), (on, 0.0),
             (lifted_a_bit, 0.0), (below, 3.0), (lifted, 0.0), (below, 1.0),
             ((0.7, 0.0, 0.0), 0.0), ((0.5, 0.0, 0.099), 1.0)]
    seen = [c.update(plat, np.array(p), f) for p, f in steps]
    assert [s[1] for s in seen] == [False, False, True, False, False, False, True, False, True,
                                    False, True]
    assert [s[2] for s in seen] == [False, False, True, False, False, False, False, False, True,
                                    False, True]
    assert c.presses == 3
    assert seen[-2][0] is None and seen[-1][0] == 0
