"""Parameters of every node: one declarative schema per parameter (type, default, range,
description), pure Python. The nodes declare their ROS parameters from these dataclasses
(``nodes/common.declare_settings``); the graph description fills them; tests validate them
without ROS.
"""

from __future__ import annotations

from dataclasses import dataclass

from .core.config import param
from .core.strategies import STRATEGIES
from .core.models import MODEL_NAMES
from .core.config import PRESETS

IMAGE_TOPIC = "/tactex/gelsight/image_raw"
CAPTURE_SERVICE = "/tactex/gelsight/capture"
PRESS_ACTION = "/tactex/press"
STATE_TOPIC = "/tactex/state"
MARKER_TOPIC = "/tactex/markers"
TOUCH_IMAGE_TOPIC = "/tactex/touch_image"
TOUCH_TOPIC = "/tactex/touch"
POSE_TOPIC = "/franka_robot_state_broadcaster/current_pose"
WRENCH_TOPIC = "/franka_robot_state_broadcaster/external_wrench_in_base_frame"
TARGET_TOPIC = "/cartesian_impedance_controller/equilibrium_pose"
RECOVERY_ACTION = "/action_server/error_recovery"


@dataclass
class GelsightSettings:
    device: str = param("", "camera: /dev/videoN, a /dev/v4l/by-id path, a name the camera "
                            "reports (e.g. 'GelSight Mini'), or a video file path")
    fps: float = param(25.0, "frame rate to read and publish at [Hz]", 1.0, 120.0)
    warmup_frames: int = param(10, "frames dropped after opening (auto-exposure settling)",
                               0, 1000)
    reference_frames: int = param(5, "frames after warm-up averaged into the no-contact frame",
                                  1, 100)
    crop_fraction: float = param(0.15, "fraction of each border cropped before resizing",
                                 0.0, 0.4)
    buffer_s: float = param(3.0, "ring buffer length [s]", 0.1, 60.0)
    frame_id: str = param("gelsight_optical_frame", "frame_id of published images")
    loop_file: bool = param(True, "restart a video file at its end (recordings only)")
    open_timeout_s: float = param(5.0, "deadline for opening the device [s]", 0.1, 60.0)


@dataclass
class MotionSettings:
    scene_file: str = param("", "scene YAML (platforms, workspace, press settings)")
    pose_topic: str = param(POSE_TOPIC, "current end-effector pose (PoseStamped) from "
                                        "franka_robot_state_broadcaster")
    wrench_topic: str = param(WRENCH_TOPIC, "external wrench in the base frame (WrenchStamped)")
    target_topic: str = param(TARGET_TOPIC, "Cartesian target pose (PoseStamped), e.g. the "
                                            "impedance controller's equilibrium pose")
    capture_service: str = param(CAPTURE_SERVICE, "GelSight capture service")
    recovery_action: str = param(RECOVERY_ACTION, "franka_msgs ErrorRecovery action "
                                                  "(used when franka_msgs is installed)")
    force_sign: float = param(1.0, "normal force = force_sign * wrench.force.z", -1.0, 1.0)
    rate_hz: float = param(50.0, "control loop rate [Hz]", 5.0, 1000.0)
    min_contact_score: float = param(0.3, "captured frame must differ from the no-contact frame "
                                          "by at least this [grey levels], else the press is "
                                          "retried (0 = no check)", 0.0, 50.0)
    state_timeout_s: float = param(1.0, "robot state older than this aborts a press [s]",
                                   0.05, 30.0)


@dataclass
class ExplorerSettings:
    scene_file: str = param("", "scene YAML (platform ids and order)")
    strategy: str = param("", "exploration strategy ('' = the preset's: infogain for default, "
                              "variance for cnn and seed_faithful)",
                          choices=("",) + tuple(STRATEGIES))
    config: str = param("default", "learner preset", choices=tuple(PRESETS))
    model: str = param("", "model variant override ('' = the preset's)",
                       choices=("", "descriptor") + MODEL_NAMES + ("auto",))
    weights: str = param("", "torchvision-format checkpoint for inception_v3 ('' = none)")
    drift_norm: bool = param(False, "remove each touch's mean colour before learning: turn on "
                                    "where the lighting drifts between touches (measured: it "
                                    "restores accuracy under drift in simulation, and cost 2 of "
                                    "24 replayed octopi-dev scenes, docs/speed_stability.md)")
    rounds: int = param(20, "decisions that request a touch after the baseline", 0, 1000)
    stop_confidence: float = param(-1.0, "stop once the belief in one platform reaches this "
                                         "(0 = never; < 0 = the preset's: 0.9 for default)",
                                   -1.0, 1.0)
    seed: int = param(0, "seed of the learner and strategy", 0, 2**31 - 1)
    record_dir: str = param("runs/trials", "folder that receives the trial record")
    trial_id: str = param("", "record sub-folder ('' = time stamp)")
    resume: str = param("", "record folder of an interrupted trial to continue ('' = a new "
                            "trial); its settings must equal this node's")
    press_action: str = param(PRESS_ACTION, "press action served by the motion node")
    press_timeout_s: float = param(120.0, "deadline for one press (all attempts) [s]",
                                   1.0, 3600.0)
    server_timeout_s: float = param(30.0, "deadline for the press server to appear [s]",
                                    0.5, 600.0)
    press_silence_s: float = param(10.0, "a press server that sends no feedback (and no goal "
                                         "answer) for this long, or that leaves the ROS graph, "
                                         "is gone: the trial ends with that reason [s]",
                                   1.0, 600.0)
    exit_when_done: bool = param(False, "shut the node down after the trial (runner, tests)")
    threads: int = param(0, "torch threads (0 = torch default)", 0, 256)
    nice: int = param(10, "CPU priority increment of this process, so training never starves "
                          "the control loop and the sensor (0 = unchanged)", 0, 19)


@dataclass
class MockArmSettings:
    scene_file: str = param("", "scene YAML (platform surfaces)")
    pose_topic: str = param(POSE_TOPIC, "where the mock publishes the current pose")
    wrench_topic: str = param(WRENCH_TOPIC, "where the mock publishes the external wrench")
    target_topic: str = param(TARGET_TOPIC, "where the mock reads target poses")
    stiffness: float = param(2000.0, "platform stiffness [N/m]", 1.0, 1e6)
    max_speed: float = param(0.3, "end-effector speed limit [m/s]", 0.001, 5.0)
    rate_hz: float = param(100.0, "simulation and publish rate [Hz]", 5.0, 1000.0)
    start_x: float = param(0.5, "start position x [m] in the base frame", -2.0, 2.0)
    start_y: float = param(0.0, "start position y [m] in the base frame", -2.0, 2.0)
    start_z: float = param(0.3, "start position z [m] in the base frame", -2.0, 2.0)
    surface_offset: float = param(0.0, "platforms' true surface z minus the scene's [m] "
                                       "(fault injection: < 0 means lower, no contact)",
                                  -0.5, 0.5)


@dataclass
class MockImageSettings:
    scene_file: str = param("", "scene YAML (what lies on each platform: sim_fabric or "
                                "replay_class)")
    source: str = param("sim", "sim[:difficulty] or replay:DIR")
    pose_topic: str = param(POSE_TOPIC, "mock arm pose, to know what is under the sensor")
    fps: float = param(25.0, "published frame rate [Hz]", 1.0, 120.0)
    depth_gain: float = param(0.2, "gel indentation [mm] per mm of penetration", 0.0, 10.0)
    buffer_s: float = param(3.0, "ring buffer length [s]", 0.1, 60.0)
    frame_id: str = param("gelsight_optical_frame", "frame_id of published images")
    seed: int = param(0, "seed of the rendered presses", 0, 2**31 - 1)
    fault_blank: float = param(0.0, "probability that a press shows no texture (fault "
                                    "injection)", 0.0, 1.0)
