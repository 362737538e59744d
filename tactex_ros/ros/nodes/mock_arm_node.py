"""mock_arm_node: stands in for the robot, franka_robot_state_broadcaster and a Cartesian
impedance controller at the robot profile's topics (``robot``, default ``sim``).

Reads equilibrium targets (PoseStamped, or multipanda_ros2's Float64MultiArray; the newest at
each simulation cycle, as a controller reads its realtime buffer), publishes the
current pose (PoseStamped) and the external wrench in the base frame (WrenchStamped, z =
``wrench_sign`` x contact force) at ``rate_hz``. The physics is ``robot.press.ArmModel`` running
the control law of the controller the profile names (``robot.press.ControlLaw``: stiffness,
damping as the controller computes it, its target filter, error clip and force rate limit, one
control cycle at the profile's ``rate_hz``) on an apparent mass against platforms of
``platform_stiffness``, so the mock behaves as that controller does: it pushes with
K (x_eq - x), not as a position follower. Like CRISP, it ignores targets while more publishers
than the profile's ``target.max_publishers`` are on the target topic.

The world's faults (``robot.mock_world.Faults``, docs/simulated_world.md), one parameter each:
``surface_offset`` (platforms lower or higher than the scene says), ``platform_stiffness``,
the wrench estimate's ``wrench_offset_*``, ``offset_gradient``, ``wrench_drift_*`` and
``wrench_noise``, the ``static_force_*`` of a payload or cable, ``coulomb_friction`` and
``viscous_friction`` (``world_seed`` draws the noise); the controller's ``max_stiffness``
clamp, ``state_filter`` and ``output_filter`` (CRISP 2.3.x) and ``activation_jump_*`` (the
transient after each activation). The published wrench is what the robot would report:
``wrench_sign`` x (contact + static force + bias + noise). Robot errors: ``reflex_force``:
above that contact force the arm stops and the state stops (the hardware
component and its controllers are down, as after a franka reflex) until a stand-in recovery
(``recovery_standin``: an action or a service) clears the error and the stand-in re-activation
services bring hardware, then controllers, back -- in that order, as franka_ros2 requires.

Time: with ``use_sim_time`` (every node of a simulated graph, ``tactex_ros.ros.simclock``) the
mock arm is the graph's clock source: each simulation cycle steps the physics by 1 / ``rate_hz``
(a late tick by up to ``SIM_CATCH_UP_CYCLES`` of them) and publishes ``rosgraph_msgs/Clock`` on
``/clock`` advanced by what it computed (never by the wall clock), every ``clock_every``
cycles (default 2: 50 Hz at 100 Hz, each /clock costs every node of the graph a wake-up); the cycle is paced to at most
real time and runs slower when starved past that bound, so the others' deadlines stretch with it. The simulated time starts at the wall clock's epoch time of
activation (stamps stay readable). Without ``use_sim_time`` (a mock beside wall-time nodes) the
physics follows the wall clock as a real arm does: up to ``CATCH_UP_S`` of missed cycles run at
the next cycle, with the newest target.

/diagnostics ``mock_arm: arm``: the real-time factor (simulated s per wall s, sim time only;
WARN "simulation behind" below ``SIM_BEHIND_RTF``), the simulated state's publish rate, hardware and controller
active, reflexes injected, targets ignored; ERROR while an injected reflex is not recovered (the
stand-in of a robot fault), WARN while targets are ignored (too many publishers).
"""

from __future__ import annotations

import threading
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, Vector3, WrenchStamped
from std_msgs.msg import Header

from .. import adapter
from ...core.errors import InputError
from ...robot.mock_world import ArmModel, ControlLaw, Faults
from ..settings import MockArmSettings
from ...robot.robots import import_interface, load_profile, with_profile
from ...robot.scene import load_scene
from .lifecycle import TactexNode
from .process import run


class MockArmNode(TactexNode):
    settings_cls = MockArmSettings

    def __init__(self, **kw) -> None:
        super().__init__("mock_arm", **kw)

    def configure(self) -> None:
        prof = load_profile(self.settings.robot)
        s = self.settings = with_profile(self.settings, prof)
        if prof.franka_state:
            raise InputError(f"robot profile {prof.name!r}: the mock arm publishes "
                             "PoseStamped + WrenchStamped state only")
        scene = load_scene(s.scene_file)
        self.scene = scene
        self.arm = ArmModel(scene, np.array([s.start_x, s.start_y, s.start_z]),
                            mock_law(prof.law, s), mass=s.mass, faults=mock_faults(s))
        # the true contact force is checked at every physics cycle (1 kHz), not only at the
        # published samples: /diagnostics counts the cycles above the scene's max_force
        self.arm.world.limit = scene.press.max_force
        # the simulation runs in its own thread (rate_loop); callbacks change the arm under this
        self.lock = threading.Lock()
        self.max_publishers = prof.max_publishers
        self.sign = s.wrench_sign
        self.quat = np.array(scene.tool_orientation)
        self.pose_pub = self.create_lifecycle_publisher(
            PoseStamped, s.pose_topic, adapter.qos_profile(prof.pose_qos))
        self.wrench_pub = self.create_lifecycle_publisher(
            WrenchStamped, s.wrench_topic,
            adapter.qos_profile(prof.wrench_qos))
        self.target_topic = s.target_topic
        # keep last 1, reliable: CRISP's rclcpp::QoS(1); only the latest target counts. Read
        # by the simulation's own thread at every cycle, as a controller reads its realtime
        # buffer: a callback on the executor's thread came up to 0.3 s late on a loaded
        # machine (the two threads share the GIL) and the arm then jumped to the newest target
        from ..latest import LatestReader
        self.target_reader = LatestReader(self.context, f"{self.get_name()}_target")
        self.target_in = self.target_reader.subscribe(import_interface(prof.target_type),
                                                      self.target_topic, 1)
        self.ignored_targets = 0      # targets dropped for too many publishers
        self.error = False            # reflex not yet cleared by the recovery
        self.hardware_active = True
        self.controller_active = True
        self.reflexes = 0
        if s.recovery_standin != "none":
            self._serve_standins(s)
        from ..diagnostics import Diagnostics, RateMeter
        self.state_meter = RateMeter()
        self._ignored_seen = (0, 0.0)     # (ignored targets, when that count was read)
        self.diag = Diagnostics(self, s.diag_period_s)
        self.diag.add("arm", f"mock arm, robot profile {prof.name} ({scene.frame_id})",
                      self._health)

    def activate(self) -> None:
        from ..simclock import RealTimeFactor, uses_sim_time
        self.sim_clock = uses_sim_time(self)
        self.rtf = RealTimeFactor()
        if self.sim_clock:
            from rosgraph_msgs.msg import Clock
            from ..simclock import CLOCK_TOPIC, clock_qos
            self._clock_msg = Clock
            self.clock_pub = self.create_publisher(Clock, CLOCK_TOPIC, clock_qos())
            self.sim_t = time.time()      # [s] simulated time, advanced by dt per cycle
            self._cycles = 0              # simulation cycles since activation
            self._publish_clock()
        self._last = self.get_clock().now().nanoseconds * 1e-9
        self._wall_last = time.monotonic()
        # a cycle (dt = 1 / rate_hz) takes at least dt / max_real_time_factor of wall time: at
        # most real time, or a forced slower pace (a starved machine's; on wall time the
        # physics catches up as ever, and the state comes that much slower)
        pace = self.settings.max_real_time_factor
        self.rate_loop(1.0 / (self.settings.rate_hz * pace), self._tick, "sim")

    # ------------------------------------------------------------------ recovery stand-ins
    def _serve_standins(self, s: MockArmSettings) -> None:
        from std_srvs.srv import SetBool, Trigger
        if s.recovery_standin == "action":
            from rclpy.action import ActionServer
            from tactex.action import Press

            def recover_action(goal_handle):
                with self.lock:
                    self.error = False
                goal_handle.succeed()
                return Press.Result(success=True)
            self._recovery_server = ActionServer(self, Press, s.recovery_name, recover_action)
        else:
            def recover_service(_req, resp):
                with self.lock:
                    resp.success, resp.message = self.error, "" if self.error else "No errors"
                    self.error = False
                return resp
            self.create_service(Trigger, s.recovery_name, recover_service)

        def hardware(req, resp):
            with self.lock:
                if self.error:
                    resp.success, resp.message = False, "robot error not cleared"
                else:
                    self.hardware_active, resp.success = bool(req.data), True
            return resp

        def controller(req, resp):
            with self.lock:
                if not self.hardware_active:
                    resp.success, resp.message = False, "hardware component not active"
                else:
                    if req.data and not self.controller_active:
                        self.arm.release()
                    self.controller_active, resp.success = bool(req.data), True
            return resp
        self.create_service(SetBool, s.hardware_service, hardware)
        self.create_service(SetBool, s.controller_service, controller)

    def _health(self) -> tuple[int, str, dict]:
        from ..diagnostics import ERROR, OK, WARN
        rate = self.state_meter.rate(self._meter_now())
        rtf = self.rtf.factor() if getattr(self, "sim_clock", False) else None
        ignored, _ = self._ignored_seen
        newly = self.ignored_targets - ignored
        self._ignored_seen = (self.ignored_targets, time.monotonic())
        values = {"state rate [Hz]": rate, "nominal rate [Hz]": self.settings.rate_hz,
                  "hardware active": self.hardware_active,
                  "controller active": self.controller_active,
                  "reflexes injected": self.reflexes, "targets ignored": self.ignored_targets,
                  "contact force [N]": float(self.arm.normal_force()),
                  "cycles over max_force (true force)": int(self.arm.world.over_limit[0]),
                  "position [m]": " ".join(f"{v:.4f}" for v in self.arm.position.copy())}
        if rtf is not None:
            values["real-time factor"] = rtf
        if self.error or not self.controller_active:
            return ERROR, ("reflex (injected): arm stopped, no state until recovered"
                           if self.error else "controller inactive: no state"), values
        if not self.active:
            return OK, "configured, not active yet: no state published", values
        over = int(self.arm.world.over_limit[0])
        if over:
            return ERROR, (f"the simulated contact force was above max_force "
                           f"({self.scene.press.max_force} N) for {over} physics cycle(s)"), values
        if newly:
            return WARN, (f"{newly} target(s) ignored since the last status: more than "
                          f"{self.max_publishers} publisher(s) on {self.target_topic}"), values
        if rtf is not None and rtf < SIM_BEHIND_RTF:
            return WARN, (f"simulation behind: real-time factor {rtf:.2f} (the machine cannot "
                          "compute the simulation in real time; simulated time runs slower, "
                          "the trial is unchanged)"), values
        return OK, (f"simulating, state at {rate:.0f} Hz" +
                    (f" (simulated time), real-time factor {rtf:.2f}" if rtf is not None
                     else "")), values

    # ------------------------------------------------------------------ loop
    def _on_target(self, msg) -> None:
        if not self.controller_active:
            return     # a deactivated controller takes no targets
        if self.max_publishers and self.count_publishers(self.target_topic) > self.max_publishers:
            self.ignored_targets += 1
            return     # as CRISP: conflicting command sources, every target ignored
        try:
            xyz, _ = adapter.target_to_array(msg)
        except InputError as exc:
            self.get_logger().warning(f"target ignored: {exc}")
            return
        with self.lock:
            self.arm.target = xyz

    def _tick(self) -> None:
        msg = self.target_in.take()        # the newest target since the last cycle
        if msg is not None:
            self._on_target(msg)
        with self.lock:
            self._step()

    def cleanup(self) -> None:
        reader, self.target_reader = getattr(self, "target_reader", None), None
        if reader is not None:
            reader.close()

    def _publish_clock(self) -> None:
        sec = int(self.sim_t)
        msg = self._clock_msg()
        msg.clock.sec, msg.clock.nanosec = sec, int(round((self.sim_t - sec) * 1e9)) % 1_000_000_000
        self.clock_pub.publish(msg)
        self.rtf.tick(self.sim_t)

    def _meter_now(self) -> float | None:
        """The state meter's clock: simulated time on the sim clock, else monotonic."""
        return self.sim_t if getattr(self, "sim_clock", False) else None

    def _step(self) -> None:
        if self.sim_clock:
            # one cycle (1 / rate_hz) of simulated time, or up to SIM_CATCH_UP_CYCLES when the
            # loop ticks late (a busy machine): the clock keeps near real time while the
            # machine can compute it, and falls behind only past that bound
            wall, pace = time.monotonic(), self.settings.max_real_time_factor
            late = (wall - self._wall_last) * self.settings.rate_hz * pace
            self._wall_last = wall
            dt = min(max(1, int(late + 0.5)), SIM_CATCH_UP_CYCLES) / self.settings.rate_hz
            self.arm.step(dt)
            self.sim_t += dt
            self._cycles += 1
            if self._cycles % self.settings.clock_every == 0:
                self._publish_clock()
            now = self.sim_t
        else:
            now = self.get_clock().now().nanoseconds * 1e-9
            self.arm.step(min(CATCH_UP_S, now - self._last))
        self._last = now
        rf = self.settings.reflex_force
        if (rf and self.controller_active and self.arm.peak_force > rf and
                self.reflexes < self.settings.reflex_limit):
            self.get_logger().error(f"reflex: contact force {self.arm.peak_force:.1f} N > "
                                    f"reflex_force {rf} N; arm stopped")
            self.arm.freeze()
            self.error, self.hardware_active, self.controller_active = True, False, False
            self.reflexes += 1
        if not self.controller_active:
            return     # the state broadcaster is down with the hardware component
        self.state_meter.tick(self._meter_now())
        self.pose_pub.publish(adapter.array_to_pose(self.arm.position, self.quat, now,
                                                    self.scene.frame_id))
        w = WrenchStamped(header=Header(stamp=adapter.stamp(now), frame_id=self.scene.frame_id))
        fx, fy, fz = (float(v) for v in self.sign * self.arm.wrench())
        w.wrench.force = Vector3(x=fx, y=fy, z=fz)
        self.wrench_pub.publish(w)


#: Most simulated time [s] one simulation cycle catches up after this process was starved or
#: stopped: a real arm moves on in real time while nobody reads its state (a starved mock
#: that ran slower than the wall clock let the press's target run ahead of it), and beyond a
#: second the arm stands, as a controller that missed its cycles stops the robot.
CATCH_UP_S = 1.0

#: On the simulated clock, the most cycles one late loop tick computes (at 100 Hz: 40 ms of
#: simulated time in one step, the state published once): with one cycle per tick, two
#: graphs on two cores ran a graph test in 53 s against 36 s on wall time; with 4, 40-43 s
SIM_CATCH_UP_CYCLES = 4

#: Below this real-time factor the mock arm's /diagnostics says WARN "simulation behind"
SIM_BEHIND_RTF = 0.5


def mock_law(law: ControlLaw, s: MockArmSettings) -> ControlLaw:
    """The profile's control law with the mock's overrides (stiffness, damping, target filter;
    a value < 0 or 0 keeps the profile's) and the controller's behaviour the settings add
    (stiffness clamp, state and output filters, activation transient; 0 = the profile's)."""
    kw: dict = {}
    if s.stiffness:
        kw["stiffness"] = s.stiffness
    if s.damping >= 0:
        kw["damping"] = s.damping
    if s.target_filter >= 0:
        kw["target_filter"] = s.target_filter
    if s.max_stiffness:
        kw["max_stiffness"] = s.max_stiffness
    for name in ("state_filter", "output_filter", "activation_jump_s"):
        if getattr(s, name):
            kw[name] = getattr(s, name)
    jump = (s.activation_jump_x, s.activation_jump_y, s.activation_jump_z)
    if any(jump):
        kw["activation_jump"] = jump
    return law.replace(**kw) if kw else law


def mock_faults(s: MockArmSettings) -> Faults:
    """The simulated world's faults from the mock's settings."""
    def vec(name: str) -> tuple[float, float, float]:
        return tuple(float(getattr(s, f"{name}_{a}")) for a in "xyz")
    return Faults(wrench_offset=vec("wrench_offset"), offset_gradient=s.offset_gradient,
                  wrench_drift=vec("wrench_drift"), wrench_noise=s.wrench_noise,
                  static_force=vec("static_force"), coulomb_friction=s.coulomb_friction,
                  viscous_friction=s.viscous_friction, surface_offset=s.surface_offset,
                  platform_stiffness=s.platform_stiffness,
                  platform_damping=s.platform_damping, seed=s.world_seed)


def main(args: list[str] | None = None) -> int:
    return run(MockArmNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
