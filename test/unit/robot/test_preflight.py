"""Pre-flight decisions (pure): the no-contact frame on recorded octopi-dev presses (no-contact
frames pass; contact, blank and saturated frames are refused), the camera and state rates,
franka's robot mode, the collision thresholds and their request, the hand-push wrench sign."""

from __future__ import annotations

import numpy as np
import pytest

from tactex_ros.core.contact import strongest_contact
from tactex_ros.core.errors import DeviceError, DeviceNotReady, InputError
from tactex_ros.robot import preflight as pf
from tactex_ros.robot.scene import PressSettings

LIMITS = pf.FrameLimits(min_std=5.0, max_saturated=0.02, max_texture=0.8, max_change=0.8)
MATERIALS = ("hairbrush_bristles", "steel_wool", "wires", "masking_tape", "aluminium_foil",
             "tissue", "cotton_ball", "sponge")


@pytest.mark.parametrize("material", MATERIALS)
def test_recorded_no_contact_frames_pass(octopi_press, material: str) -> None:
    frames = octopi_press(material, 1)
    assert pf.frame_problem(list(frames[:5]), LIMITS) is None


@pytest.mark.parametrize("material", ["hairbrush_bristles", "steel_wool", "wires",
                                      "masking_tape", "aluminium_foil", "tissue"])
def test_recorded_contact_is_refused(octopi_press, material: str) -> None:
    """Frames around the strongest contact of a recorded press, as if the sensor started in
    contact: refused (textured materials by their texture)."""
    frames = octopi_press(material, 1)
    i, _ = strongest_contact(frames)
    problem = pf.frame_problem(list(frames[i - 2:i + 3]), LIMITS)
    assert problem is not None and problem.check in ("contact", "unsteady")
    if material in ("hairbrush_bristles", "steel_wool", "wires"):
        assert problem.check == "contact"


def test_blank_and_saturated_frames_are_refused(octopi_press) -> None:
    nc = octopi_press("tissue", 1)[:5]
    dark = [(f // 40).astype(np.uint8) for f in nc]          # LED off: a few grey levels
    assert pf.frame_problem(dark, LIMITS).check == "blank"
    black = [np.zeros_like(nc[0])] * 3
    assert pf.frame_problem(black, LIMITS).check == "blank"
    bright = [np.clip(f.astype(int) * 3, 0, 255).astype(np.uint8) for f in nc]
    assert pf.frame_problem(bright, LIMITS).check == "saturated"
    assert pf.frame_problem([], LIMITS).check == "no_frame"


def test_rates() -> None:
    t = list(np.arange(0, 1.0, 0.01))          # 100 Hz
    assert pf.rate_hz(t) == pytest.approx(100.0)
    assert pf.rate_hz([]) == 0.0 and pf.rate_hz([1.0]) == 0.0
    assert pf.state_problem(t, 50.0, 1.0, "/s") is None
    assert pf.state_problem(t, 200.0, 1.0, "/s").check == "state_rate"
    assert pf.state_problem([], 50.0, 1.0, "/s").check == "state"
    # nothing at all is a device absent (exit status 1); a slow stream is what the machine
    # did, not what the user wrote (issue 49): a run-time state, exit status 1 too
    assert isinstance(pf.state_problem([], 50.0, 1.0, "/s").error(), DeviceError)
    slow = pf.state_problem(t, 200.0, 1.0, "/s").error()
    assert isinstance(slow, DeviceNotReady) and not isinstance(slow, InputError)
    assert "state stream was slow" in str(slow) and "100.0 Hz" in str(slow)
    assert isinstance(pf.frame_problem([], LIMITS).error(), DeviceError)
    assert pf.fps_problem(list(np.arange(25) / 25.0), 25.0, 0.8) is None
    assert pf.fps_problem(list(np.arange(25) / 15.0), 25.0, 0.8).check == "fps"


def test_robot_mode() -> None:
    assert pf.mode_problem(None) is None and pf.mode_problem(pf.ROBOT_MODE_MOVE) is None
    for mode in (0, 1, 3, 4, 5, 6, 9):
        assert pf.mode_problem(mode).check == "robot_mode"
    # a user stop is a fault like a reflex (the arm follows nothing until recovered)
    assert (pf.fault_mode(4), pf.fault_mode(5)) == ("reflex", "user stopped")
    assert [pf.fault_mode(m) for m in (None, 0, 1, 2, 3, 6)] == [""] * 6


def _multipanda_stamps(frequency: int, seconds: float, update_hz: float = 1000.0,
                       lag_s: float = 2e-5) -> list[float]:
    """Publish times [s] of multipanda's state broadcaster (8b6a92c
    franka_robot_state_broadcaster.cpp:88-104): at each update (``update_hz``) it publishes
    when ``time - last_pub >= 1e9 / frequency`` ns, ``last_pub`` being the node's clock just
    after publishing (``lag_s`` after the update's time)."""
    out, last = [], -1.0
    for i in range(int(seconds * update_hz)):
        t = i / update_hz
        if t - last < 1.0 / frequency:
            continue
        out.append(t)
        last = t + lag_s
    return out


def test_panda_state_rate_of_the_bring_up_passes_the_profile() -> None:
    """The Panda's state at the bring-up's `frequency` (config/bringup/
    panda_crisp_controller.yaml) passes the profile's min_rate_hz; multipanda's default 30 Hz
    is refused."""
    import yaml

    from tactex_ros.core.paths import config_dir
    from tactex_ros.robot.robots import load_profile
    prof = load_profile("panda_crisp")
    bringup = yaml.safe_load((config_dir() / "bringup" / "panda_crisp_controller.yaml")
                             .read_text())
    freq = bringup["franka_robot_state_broadcaster"]["ros__parameters"]["frequency"]
    stamps = _multipanda_stamps(freq, 1.0)
    assert 195.0 <= pf.rate_hz(stamps) <= 250.0          # every 5th cycle: 200 Hz
    assert pf.state_problem(stamps, prof.min_state_rate_hz, 1.0, prof.state_topic) is None
    slow = pf.state_problem(_multipanda_stamps(30, 1.0), prof.min_state_rate_hz, 1.0,
                            prof.state_topic)
    assert slow.check == "state_rate"


def test_collision_request_fits_the_press() -> None:
    """The shipped request (config/bringup/collision_thresholds.yaml, upper force 25 N)
    against the press; the command carries every field."""
    from tactex_ros.robot.robots import load_profile
    col = load_profile("fr3_crisp").collision
    press = PressSettings()
    assert pf.collision_problem(col.request, 12.0, press.tare_max_offset_n) is None
    assert pf.collision_problem(col.request, 22.0, 5.0).check == "collision"      # 27 > 25
    bad = dict(col.request, lower_force_thresholds_nominal=[40.0] * 6)
    assert pf.collision_problem(bad, 12.0, 5.0).check == "collision"
    assert pf.collision_problem({}, 12.0, 5.0).check == "collision"
    cmd = pf.collision_command(col.service, col.type, col.request)
    assert cmd.startswith("ros2 service call /service_server/set_force_torque_collision_"
                          "behavior franka_msgs/srv/SetForceTorqueCollisionBehavior ")
    assert "upper_force_thresholds_nominal: [25, 25, 25, 35, 35, 35]" in cmd
    assert "lower_torque_thresholds_nominal: [25, 25, 22, 20, 19, 17, 14]" in cmd


def test_push_sign() -> None:
    rng = np.random.default_rng(0)
    base = list(0.7 + 0.1 * rng.standard_normal(100))
    t = np.arange(0, 2.0, 0.01)
    up = np.where(t > 0.5, -8.0, 0.7) + 0.1 * rng.standard_normal(len(t))   # reads -z
    r = pf.push_sign(base, t, up, push_n=5.0, hold_s=0.2)
    assert r.force_sign == -1 and r.delta_n == pytest.approx(-8.7, abs=0.2)
    assert pf.push_sign(base, t, -up + 1.4, 5.0, 0.2).force_sign == 1
    blip = np.where((t > 0.5) & (t < 0.6), 9.0, 0.7)                       # too short
    assert pf.push_sign(base, t, blip, 5.0, 0.2).force_sign == 0
    assert pf.push_sign(base, t, np.full(len(t), 0.7), 5.0, 0.2).force_sign == 0


def test_each_problem_raises_the_error_of_its_meaning() -> None:
    """A device absent (no state), not ready (robot mode) or measured slow (state rate: what
    the machine did) is a run-time state (exit status 1); an unfit setting is bad input (exit
    status 2)."""
    from tactex_ros.core.errors import DeviceError, DeviceNotReady, InputError, TrialError
    not_ready = pf.mode_problem(4).error()
    assert isinstance(not_ready, DeviceNotReady) and isinstance(not_ready, TrialError)
    assert not isinstance(not_ready, InputError)
    absent = pf.state_problem([], 100.0, 1.0, "/robot_state").error()
    assert isinstance(absent, DeviceError) and not isinstance(absent, DeviceNotReady)
    slow = pf.state_problem([0.0, 1.0], 100.0, 1.0, "/robot_state").error()
    assert isinstance(slow, DeviceNotReady) and not isinstance(slow, InputError)
