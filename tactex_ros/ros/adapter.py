"""The one place where ROS messages and numpy arrays meet (no node, no ``rclpy.init`` needed).

Images: ``sensor_msgs/Image`` rgb8 or bgr8 (240 x 320) <-> RGB uint8 (240, 320, 3).
Poses: ``geometry_msgs/PoseStamped`` <-> position (3,) [m] + quaternion (4,) x y z w.
Wrenches: ``geometry_msgs/WrenchStamped`` -> normal force [N] (sign configurable).
Robot interfaces of a robot profile (``robot/robots.py``): equilibrium targets as PoseStamped or
multipanda_ros2's ``Float64MultiArray`` (x y z + rotation matrix row by row); franka state
messages (``o_t_ee`` column-major 4x4, ``o_f_ext_hat_k``) -> position, force, robot mode.
Exploration: ``RoundRecord`` -> ``tactex/ExplorationState``; scene + state ->
``visualization_msgs/MarkerArray`` for rviz.
"""

from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Vector3
from sensor_msgs.msg import Image
from std_msgs.msg import ColorRGBA, Float64MultiArray, Header
from visualization_msgs.msg import Marker, MarkerArray

from ..core.errors import InputError
from ..core.touch import FRAME_H, FRAME_W
from ..robot.scene import Scene


def stamp(seconds: float) -> Time:
    """Float seconds -> builtin_interfaces/Time."""
    sec = math.floor(seconds)
    return Time(sec=int(sec), nanosec=int(round((seconds - sec) * 1e9)) % 1_000_000_000)


def seconds(t: Time) -> float:
    return t.sec + t.nanosec * 1e-9


# ---------------------------------------------------------------------- images
def image_to_array(msg: Image, what: str = "image") -> np.ndarray:
    """``sensor_msgs/Image`` (rgb8 | bgr8, 320 x 240) -> RGB uint8 (240, 320, 3).

    Raises InputError naming what is wrong (encoding, size, step, data length, blank frame).
    """
    if msg.encoding not in ("rgb8", "bgr8"):
        raise InputError(f"{what}: encoding {msg.encoding!r} not supported (rgb8, bgr8)")
    if (msg.height, msg.width) != (FRAME_H, FRAME_W):
        raise InputError(f"{what}: size {msg.width}x{msg.height}, expected "
                         f"{FRAME_W}x{FRAME_H}")
    if msg.step < msg.width * 3:
        raise InputError(f"{what}: step {msg.step} < width * 3 = {msg.width * 3}")
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if data.size != msg.step * msg.height:
        raise InputError(f"{what}: {data.size} bytes of data, expected step * height = "
                         f"{msg.step * msg.height}")
    arr = data.reshape(msg.height, msg.step)[:, :msg.width * 3].reshape(msg.height,
                                                                        msg.width, 3)
    if msg.encoding == "bgr8":
        arr = arr[:, :, ::-1]
    arr = np.ascontiguousarray(arr)
    if int(arr.max()) == int(arr.min()):
        raise InputError(f"{what}: constant image (value {int(arr.max())}): no sensor signal")
    return arr


def images_to_frames(msgs: list[Image], what: str = "touch") -> np.ndarray | None:
    """A touch's further in-contact frames (``tactex/Touch.extra_images``) -> RGB uint8
    (K, 240, 320, 3), the ``core.touch.Touch.extra`` of the touch; None when there are none.
    InputError (``image_to_array``'s, naming the frame) when one is unusable."""
    if not msgs:
        return None
    return np.stack([image_to_array(m, f"{what}, extra frame {k + 1} of {len(msgs)}")
                     for k, m in enumerate(msgs)])


def array_to_image(rgb: np.ndarray, t: float, frame_id: str) -> Image:
    """RGB uint8 (H, W, 3) -> ``sensor_msgs/Image`` rgb8 stamped ``t`` [s]."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise InputError(f"image array must be (H, W, 3), got {rgb.shape}")
    h, w = rgb.shape[:2]
    return Image(header=Header(stamp=stamp(t), frame_id=frame_id), height=h, width=w,
                 encoding="rgb8", is_bigendian=0, step=w * 3, data=rgb.tobytes())


# ---------------------------------------------------------------------- poses and wrenches
def pose_to_array(msg: PoseStamped | Pose) -> tuple[np.ndarray, np.ndarray]:
    """Pose -> position (3,) [m], quaternion (4,) x y z w; InputError if not finite."""
    p = msg.pose if isinstance(msg, PoseStamped) else msg
    xyz = np.array([p.position.x, p.position.y, p.position.z])
    q = np.array([p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w])
    if not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(q))):
        raise InputError("pose with non-finite values")
    return xyz, q


def array_to_pose(xyz: np.ndarray, quat: np.ndarray, t: float, frame_id: str) -> PoseStamped:
    """Position (3,) [m] + quaternion (4,) x y z w -> PoseStamped stamped ``t`` [s]."""
    return PoseStamped(header=Header(stamp=stamp(t), frame_id=frame_id),
                       pose=Pose(position=Point(x=float(xyz[0]), y=float(xyz[1]),
                                                z=float(xyz[2])),
                                 orientation=Quaternion(x=float(quat[0]), y=float(quat[1]),
                                                        z=float(quat[2]), w=float(quat[3]))))


def normal_force(force: Vector3, sign: float = 1.0) -> float:
    """Normal (pressing) force [N] from a base-frame force vector: ``sign * f_z``, >= 0.

    franka's external wrench is the wrench the environment exerts on the end effector, so a
    downward press reads as +z (sign +1)."""
    f = sign * float(force.z)
    if not math.isfinite(f):
        raise InputError("wrench with a non-finite force")
    return max(0.0, f)


def force_components(force: Vector3 | np.ndarray, sign: float = 1.0) -> tuple[float, float]:
    """(signed normal force ``sign * f_z`` [N], force magnitude [N]) of a base-frame force;
    InputError if not finite. The magnitude does not depend on the sign convention, so the
    force limit holds even where ``sign`` is wrong."""
    f = (np.array([force.x, force.y, force.z], dtype=float) if isinstance(force, Vector3)
         else np.asarray(force, dtype=float)[:3])
    if not np.all(np.isfinite(f)):
        raise InputError("wrench with a non-finite force")
    return float(sign * f[2]), float(np.linalg.norm(f))


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternion x y z w -> rotation matrix (3, 3)."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) -> unit quaternion x y z w (w >= 0)."""
    r = np.asarray(r, dtype=float)
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([x, y, z, w])
    return q / np.linalg.norm(q)


def target_msg(kind: str, xyz: np.ndarray, quat: np.ndarray, t: float, frame_id: str):
    """An equilibrium target of the profile's ``kind`` (``geometry_msgs/msg/PoseStamped`` or
    ``std_msgs/msg/Float64MultiArray``: x y z then the rotation matrix row by row, 12 values)."""
    if kind == "std_msgs/msg/Float64MultiArray":
        r = quat_to_matrix(quat)
        return Float64MultiArray(data=[float(v) for v in xyz] + [float(v) for v in r.ravel()])
    return array_to_pose(xyz, quat, t, frame_id)


def target_to_array(msg) -> tuple[np.ndarray, np.ndarray]:
    """A PoseStamped or 12-value Float64MultiArray target -> position (3,), quaternion (4,)."""
    if isinstance(msg, Float64MultiArray):
        d = np.asarray(msg.data, dtype=float)
        if d.shape != (12,) or not np.all(np.isfinite(d)):
            raise InputError(f"Float64MultiArray target: expected 12 finite values (x y z + "
                             f"rotation row by row), got {d.size}")
        return d[:3].copy(), matrix_to_quat(d[3:].reshape(3, 3))
    return pose_to_array(msg)


FRANKA_MODE_REFLEX = 4     # franka_msgs/FrankaState.ROBOT_MODE_REFLEX


def franka_state_to_array(msg, sign: float) -> tuple[np.ndarray, float, float, int]:
    """A franka state message (``o_t_ee`` 16 values column-major, ``o_f_ext_hat_k`` 6 values,
    ``robot_mode``) -> (position (3,) [m], signed normal force [N], force magnitude [N],
    robot mode)."""
    t = np.asarray(msg.o_t_ee, dtype=float)
    f = np.asarray(msg.o_f_ext_hat_k, dtype=float)
    if t.shape != (16,) or f.shape != (6,) or not (np.all(np.isfinite(t)) and
                                                   np.all(np.isfinite(f))):
        raise InputError("franka state: o_t_ee must hold 16 and o_f_ext_hat_k 6 finite values")
    fn, mag = force_components(f[:3], sign)
    return t[12:15].copy(), fn, mag, int(getattr(msg, "robot_mode", 0))


# ---------------------------------------------------------------------- exploration state
def state_msg(rec, *, trial_id: str, strategy: str, platform_ids: list[str],
              reference_touches: int, done: bool, prediction: str, t: float, frame_id: str,
              reference_id: str = "reference", sure: bool = False):
    """A core ``RoundRecord`` -> ``tactex/ExplorationState`` (platform_ids: comparisons).

    ``rec.platform`` 0 (the reference touched again) becomes ``reference_id``; a strategy that
    also scored the reference ((C + 1,) scores) reports the comparisons' scores as uncertainty.
    ``sure``: the trial ended with the belief at the stop threshold (``TrialEngine.sure``).
    """
    from tactex.msg import ExplorationState
    nxt = ("" if rec.platform is None else reference_id if rec.platform == 0
           else platform_ids[rec.platform - 1])
    scores = list(rec.scores or [0.0] * len(rec.probs))[-len(rec.probs):]
    return ExplorationState(
        header=Header(stamp=stamp(t), frame_id=frame_id), trial_id=trial_id,
        round=int(rec.round), strategy=strategy, model=rec.model,
        platform_ids=list(platform_ids), belief=[float(v) for v in rec.probs],
        uncertainty=[float(v) for v in scores],
        touches=[int(v) for v in rec.touches], reference_touches=int(reference_touches),
        next_platform=nxt, train_s=float(rec.train_s), score_s=float(rec.score_s),
        decision_s=float(rec.decision_s), done=bool(done), prediction=prediction,
        sure=bool(done and sure))


def _belief_colour(b: float, highlight: bool) -> ColorRGBA:
    """Blue (belief 0) -> red (belief 1); the next target is drawn opaque and brighter."""
    b = float(np.clip(b, 0.0, 1.0))
    return ColorRGBA(r=b, g=0.2, b=1.0 - b, a=1.0 if highlight else 0.6)


def markers(scene: Scene, state, t: float) -> MarkerArray:
    """rviz markers: one cube per platform at its pose coloured by belief, a text label with
    touches and uncertainty, the next target highlighted (bigger, opaque, yellow outline)."""
    out = MarkerArray()
    hdr = Header(stamp=stamp(t), frame_id=scene.frame_id)
    belief = dict(zip(state.platform_ids, state.belief, strict=True)) if state is not None else {}
    unc = dict(zip(state.platform_ids, state.uncertainty, strict=True)) if state is not None else {}
    touches = dict(zip(state.platform_ids, state.touches, strict=True)) if state is not None else {}
    nxt = state.next_platform if state is not None else ""
    for i, p in enumerate(scene.ordered):
        x, y, z = p.position
        ref = p.role == "reference"
        hl = p.id == nxt or (state is not None and state.done and p.id == state.prediction)
        side = 2 * p.radius * (1.2 if hl else 1.0)
        cube = Marker(header=hdr, ns="platforms", id=i, type=Marker.CUBE, action=Marker.ADD)
        cube.pose.position = Point(x=x, y=y, z=z - 0.005)
        cube.pose.orientation.w = 1.0
        cube.scale = Vector3(x=side, y=side, z=0.01)
        cube.color = (ColorRGBA(r=0.8, g=0.8, b=0.8, a=0.8) if ref
                      else _belief_colour(belief.get(p.id, 0.0), hl))
        label = Marker(header=hdr, ns="labels", id=i, type=Marker.TEXT_VIEW_FACING,
                       action=Marker.ADD)
        label.pose.position = Point(x=x, y=y, z=z + 0.04)
        label.pose.orientation.w = 1.0
        label.scale.z = 0.02
        label.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
        if ref:
            label.text = f"{p.id} (touches {state.reference_touches if state else 0})"
        else:
            label.text = (f"{p.id}  p={belief.get(p.id, 0.0):.2f}  "
                          f"u={unc.get(p.id, 0.0):.3g}  n={touches.get(p.id, 0)}")
        out.markers += [cube, label]
        if hl:
            ring = Marker(header=hdr, ns="next", id=0, type=Marker.CYLINDER, action=Marker.ADD)
            ring.pose.position = Point(x=x, y=y, z=z - 0.012)
            ring.pose.orientation.w = 1.0
            ring.scale = Vector3(x=2.8 * p.radius, y=2.8 * p.radius, z=0.004)
            ring.color = ColorRGBA(r=1.0, g=0.9, b=0.0, a=1.0)
            out.markers.append(ring)
    return out


def qos_profile(q):
    """A robot profile's ``Qos`` (its upstream publisher's reliability and keep-last depth,
    volatile) as an rclpy ``QoSProfile``: the subscription asks for exactly what the publisher
    offers."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    rel = (ReliabilityPolicy.BEST_EFFORT if q.reliability == "best_effort"
           else ReliabilityPolicy.RELIABLE)
    return QoSProfile(depth=q.depth, history=HistoryPolicy.KEEP_LAST, reliability=rel,
                      durability=DurabilityPolicy.VOLATILE)


def latched_qos():
    """Reliable, transient-local, depth 1: a subscriber that joins late (rviz, Foxglove,
    ``ros2 topic echo``) receives the last message at once. Subscribers must ask for
    transient-local durability too (config/tactex.rviz does)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
