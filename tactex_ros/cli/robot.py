"""``tactex robot check-wrench``: the wrench sign of a robot profile, checked with a hand push.

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
