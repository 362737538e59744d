"""``tactex robot check-wrench``: the wrench sign of a robot profile, checked with a hand push;
``tactex robot measure-scene``: the platforms' surfaces measured with light presses
(``robot/measure.py``), written into a corrected scene file (docs/hardware_checks.md).

With the robot's bring-up running and the arm held by its controller (or in guiding mode), the
command reads the profile's external wrench (base frame) for ``--baseline-s`` with hands off,
then asks for a push of the sensor *upwards* (as a platform pushes it during a press) and
watches the wrench up to ``--deadline-s``. A push of ``--push-n`` or more held for
``--hold-s`` gives the sign that makes that push read as a positive normal force. Exit status:
0 the profile's ``force_sign`` is right, 1 it is wrong or no push was seen (the reason is
printed), 2 bad input (docs/hardware_checks.md, "Wrench sign")."""

from __future__ import annotations

import argparse
import json
import sys

from .options import bounded, builds


def cmd_check_wrench(args: argparse.Namespace) -> int:
    import rclpy
    from geometry_msgs.msg import WrenchStamped

    from ..robot.robots import import_interface, load_profile
    from ..ros.adapter import qos_profile
    from ..ros.preflight import Probe, Stopped, watch_push

    prof = load_profile(args.robot)
    # the subscription asks for the upstream publisher's QoS (franka's wrench: best effort,
    # keep last 1; a reliable reader would never match it)
    if prof.franka_state:
        msg_type, topic = import_interface(prof.state_type), args.topic or prof.state_topic
        qos = qos_profile(prof.state_qos)

        def fz_of(msg):
            return msg.o_f_ext_hat_k[2]
    else:
        msg_type, topic = WrenchStamped, args.topic or prof.wrench_topic
        qos = qos_profile(prof.wrench_qos)

        def fz_of(msg):
            return msg.wrench.force.z
    sign = args.force_sign or prof.force_sign

    def prompt() -> None:
        print(f"now push the sensor UP by hand with about {2 * args.push_n:g} N and hold it "
              f"({args.deadline_s:g} s)", file=sys.stderr, flush=True)

    rclpy.init()
    probe = None
    try:
        probe = Probe(rclpy.get_default_context(), "tactex_check_wrench")
        print(f"reading {topic} hands off for {args.baseline_s:g} s ...", file=sys.stderr,
              flush=True)
        reading, n_base, n_push = watch_push(probe, msg_type, topic, qos, fz_of,
                                             args.baseline_s, args.deadline_s, args.push_n,
                                             args.hold_s, prompt)
    except Stopped:
        return 130
    finally:
        if probe is not None:
            probe.close()
        rclpy.try_shutdown()
    out = {"robot": prof.name, "topic": topic, "baseline_fz_n": round(reading.baseline_n, 3),
           "push_delta_fz_n": round(reading.delta_n, 3), "samples": [n_base, n_push],
           "measured_force_sign": reading.force_sign, "profile_force_sign": sign}
    if reading.force_sign == 0:
        out["result"] = (f"no push of {args.push_n:g} N held {args.hold_s:g} s within "
                         f"{args.deadline_s:g} s: nothing decided")
        code = 1
    elif reading.force_sign == sign:
        out["result"] = f"force_sign {sign:+g} is right for {prof.name}"
        code = 0
    else:
        out["result"] = (f"force_sign {sign:+g} of {prof.name} is WRONG: an upward push reads "
                         f"{reading.delta_n:+.1f} N in f_z, so force_sign must be "
                         f"{reading.force_sign:+d} (profile force_sign, or the motion node "
                         "parameter force_sign)")
        code = 1
    print(json.dumps(out, indent=2))
    return code


def add_commands(sub, command: str | None = None) -> None:
    r = sub.add_parser("robot", help="checks on the real robot")
    if not builds(command, "robot"):
        return
    rsub = r.add_subparsers(dest="rcmd", required=True)
    c = rsub.add_parser("check-wrench", help="the wrench sign, checked with a hand push")
    c.add_argument("--robot", default="fr3_crisp", help="robot profile (name or file)")
    c.add_argument("--topic", default="", help="wrench (or franka state) topic "
                                               "(default: the profile's)")
    c.add_argument("--force-sign", type=float, default=0.0, choices=(-1.0, 0.0, 1.0),
                   help="the sign to check (default 0: the profile's)")
    c.add_argument("--baseline-s", type=bounded(float, 0.1, 60.0), default=1.0,
                   help="hands-off reading [s] (0.1..60)")
    c.add_argument("--deadline-s", type=bounded(float, 0.5, 600.0), default=20.0,
                   help="how long to wait for the push [s] (0.5..600)")
    c.add_argument("--push-n", type=bounded(float, 0.5, 50.0), default=5.0,
                   help="smallest change of f_z that counts as the push [N] (0.5..50)")
    c.add_argument("--hold-s", type=bounded(float, 0.0, 10.0), default=0.2,
                   help="the push must last this long [s] (0..10)")
    c.set_defaults(func=cmd_check_wrench)
    add_measure_scene(rsub)


def cmd_measure_scene(args: argparse.Namespace) -> int:
    """Light presses on every platform (or ``--platforms``); writes the corrected scene. Before
    the arm moves, the motion node's pre-flight (``ros.preflight.robot_preflight``; off with
    ``--no-preflight``): a refusal names the problem, exit 1 (state silent or slow, not in move
    mode) or 2 (another graph, collision thresholds), nothing published to the target."""
    import time

    import numpy as np
    import rclpy
    from dataclasses import replace
    from geometry_msgs.msg import PoseStamped, WrenchStamped
    from rclpy.qos import qos_profile_sensor_data

    from ..core.errors import InputError
    from ..core.outputs import write_bytes
    import yaml

    from ..core.paths import read_yaml
    from ..robot.measure import corrected_scene, light_press
    from ..robot.press import PressController, check_press
    from ..robot.robots import import_interface, load_profile, with_profile
    from ..robot.scene import load_scene
    from ..ros import adapter
    from ..ros.preflight import Probe, Stopped, arm_topics, robot_preflight
    from ..ros.settings import MotionSettings

    prof = load_profile(args.robot)
    if prof.franka_state:
        raise InputError(f"robot profile {prof.name!r}: measure-scene reads PoseStamped + "
                         "WrenchStamped state (pose_topic + wrench_topic profiles)")
    scene = load_scene(args.scene)
    scene = replace(scene, press=light_press(scene.press, args.force_n, args.search_m))
    check_press(scene, prof.stiffness, f"scene {args.scene} (light press)",
                prof.law.error_clip)
    ids = [p.id for p in scene.platforms]
    wanted = args.platforms.split(",") if args.platforms else ids
    for pid in wanted:
        scene.platform(pid)      # InputError names the unknown id and the scene's
    # the motion node's pre-flight settings, the profile's topics and rate filled in
    checked = with_profile(MotionSettings(
        robot=args.robot, preflight=not args.no_preflight,
        preflight_deadline_s=args.state_deadline_s, min_state_rate_hz=args.min_state_rate_hz,
        collision_set_by_hand=args.collision_set_by_hand), prof)
    state: dict = {}

    def on_pose(msg) -> None:
        state["xyz"], _ = adapter.pose_to_array(msg.pose)
        state["pose_t"] = time.monotonic()

    def on_wrench(msg) -> None:
        state["f"] = adapter.force_components(msg.wrench.force, prof.force_sign)
        state["wrench_t"] = time.monotonic()

    rclpy.init()
    probe = None
    found: dict[str, float] = {}
    report: dict = {"robot": prof.name, "scene": str(args.scene), "force_n": args.force_n,
                    "platforms": {}}
    try:
        probe = Probe(rclpy.get_default_context(), "tactex_measure_scene")
        node = probe.node
        node.create_subscription(PoseStamped, prof.pose_topic, on_pose,
                                 qos_profile_sensor_data)
        node.create_subscription(WrenchStamped, prof.wrench_topic, on_wrench,
                                 qos_profile_sensor_data)
        # created before the pre-flight, as the motion node's: a second publisher of the
        # target is another graph; nothing is published until the pre-flight passed
        pub = node.create_publisher(import_interface(prof.target_type), prof.target_topic, 10)
        if checked.preflight:
            graph = arm_topics(checked, prof)
            robot_preflight(probe, prof, scene.press, checked, graph, node.get_logger(),
                            by_hand="--collision-set-by-hand")
            # one graph per arm until the first target, as the motion node's until its first
            # goal: discovery is given its time (the arm moves right after)
            problem = probe.settled_graph(graph)
            if problem:
                raise InputError(f"pre-flight: {problem}")
        else:
            print("pre-flight off (--no-preflight): robot state rate, one graph per arm, "
                  "robot mode and collision thresholds not checked", file=sys.stderr,
                  flush=True)
        end = time.monotonic() + args.state_deadline_s
        while ("xyz" not in state or "f" not in state) and time.monotonic() < end:
            probe._spin()
        if "xyz" not in state or "f" not in state:
            print(json.dumps({**report, "result": f"no robot state on {prof.pose_topic} and "
                              f"{prof.wrench_topic} within {args.state_deadline_s} s"},
                             indent=2))
            return 1
        quat = np.array(scene.tool_orientation)
        period = 1.0 / args.rate_hz
        for pid in wanted:
            p = scene.platform(pid)
            ctrl = PressController(scene, p, state["xyz"], time.monotonic(),
                                   stiffness=prof.stiffness, capture=False,
                                   period_s=period, hold_s=args.state_hold_s)
            stopped = ""
            while not ctrl.done:
                now = time.monotonic()
                tick = now + period
                age = now - min(state["pose_t"], state["wrench_t"])
                if age > args.state_timeout_s:       # the robot does not follow: stop here
                    stopped = (f"robot state stopped: the newest is {age:.2f} s old, over "
                               f"--state-timeout-s {args.state_timeout_s} s")
                    break
                target = ctrl.step(now, state["xyz"], *state["f"], state_age_s=age)
                pub.publish(adapter.target_msg(prof.target_type, target, quat,
                                               node.get_clock().now().nanoseconds * 1e-9,
                                               scene.frame_id))
                while time.monotonic() < tick:
                    probe._spin()
            out = ctrl.outcome()
            entry = {"scene_z": p.position[2], "success": out.success and not stopped}
            if stopped:
                entry["reason"] = stopped
                report["platforms"][pid] = entry
                print(f"{pid}: {json.dumps(entry)}", file=sys.stderr, flush=True)
                print(json.dumps({**report, "result": stopped}, indent=2))
                return 1
            if out.success and out.surface_z is not None:
                found[pid] = out.surface_z
                entry.update(found_z=round(out.surface_z, 5),
                             moved_mm=round((out.surface_z - p.position[2]) * 1000, 2),
                             force_n=round(out.force_n, 2))
            else:
                entry["reason"] = out.reason or "the surface was not found"
            report["platforms"][pid] = entry
            print(f"{pid}: {json.dumps(entry)}", file=sys.stderr, flush=True)
    except Stopped:
        return 130
    finally:
        if probe is not None:
            probe.close()
        rclpy.try_shutdown()
    if found:          # --out was checked before the first press (cli.main.check_outputs)
        write_bytes(args.out, yaml.safe_dump(corrected_scene(read_yaml(args.scene, "scene file"),
                                                             found), sort_keys=False).encode())
        load_scene(args.out)      # what was written is a valid scene
        report["written"] = str(args.out)
    missing = [pid for pid in wanted if pid not in found]
    report["result"] = ("every platform measured" if not missing else
                        f"not measured (kept as they were): {missing}")
    print(json.dumps(report, indent=2))
    return 1 if missing else 0


def add_measure_scene(rsub) -> None:
    m = rsub.add_parser("measure-scene", help="measure the platforms' surfaces with light "
                                              "presses and write the corrected scene")
    m.add_argument("--scene", required=True, help="scene YAML to measure")
    m.add_argument("--out", required=True, help="where the corrected scene YAML is written "
                                                "(.yaml; checked before the first press)")
    m.add_argument("--robot", default="fr3_crisp", help="robot profile (name or file)")
    m.add_argument("--platforms", default="", help="comma-separated platform ids (default: "
                                                   "all)")
    m.add_argument("--force-n", type=bounded(float, 0.5, 10.0), default=2.0,
                   help="the light press's force [N] (0.5..10)")
    m.add_argument("--search-m", type=bounded(float, 0.0, 0.05), default=0.02,
                   help="how far below the scene's surface to look for it [m] (0..0.05)")
    m.add_argument("--rate-hz", type=bounded(float, 5.0, 500.0), default=50.0,
                   help="control loop rate [Hz] (5..500)")
    m.add_argument("--state-deadline-s", type=bounded(float, 0.5, 60.0), default=5.0,
                   help="the robot state (and franka's collision service) must answer within "
                        "this [s] (0.5..60; the motion node's preflight_deadline_s)")
    from ..ros.settings import MotionSettings
    motion = MotionSettings.model_fields
    m.add_argument("--min-state-rate-hz", type=bounded(float, 0.0, 10000.0),
                   default=motion["min_state_rate_hz"].default,
                   help="robot state slower than this refuses the start, exit 1 [Hz] "
                        "(0 = the profile's state.min_rate_hz; the motion node's "
                        "min_state_rate_hz)")
    m.add_argument("--collision-set-by-hand", action="store_true",
                   help="franka's collision thresholds were set with the `ros2 service call` "
                        "a refused start printed (the motion node's collision_set_by_hand)")
    m.add_argument("--no-preflight", action="store_true",
                   help="skip the pre-flight (robot state rate, one graph per arm, robot "
                        "mode, collision thresholds; the motion node's preflight: false)")
    m.add_argument("--state-hold-s", type=bounded(float, 0.01, 30.0),
                   default=motion["state_hold_s"].default,
                   help="robot state older than this holds the target where it is [s] "
                        "(0.01..30; the motion node's state_hold_s)")
    m.add_argument("--state-timeout-s", type=bounded(float, 0.05, 30.0),
                   default=motion["state_timeout_s"].default,
                   help="robot state older than this ends the measurement, exit 1 [s] "
                        "(0.05..30; the motion node's state_timeout_s)")
    m.set_defaults(func=cmd_measure_scene)
