"""Parameters of every node, in the one schema system (``core/config.py``: type, default,
range, choices, description), pure Python. The nodes declare their ROS parameters from these
models (``nodes/lifecycle.declare_settings``); the graph description fills and checks them; tests
validate them without ROS. Every topic, service and action name is a parameter.

The explorer's settings are composed from the core's: ``ExplorerSettings`` is a
``TrialSettings`` (preset ``config`` + ``learner.*`` + ``trial.*``, the preset's values where
not given) plus the node's own parameters.
"""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from ..core.config import TrialSettings
from ..core.schema import FieldError, Schema, param

IMAGE_TOPIC = "/tactex/gelsight/image_raw"
CAPTURE_SERVICE = "/tactex/gelsight/capture"
PRESS_ACTION = "/tactex/press"
STATE_TOPIC = "/tactex/state"
MARKER_TOPIC = "/tactex/markers"
TOUCH_IMAGE_TOPIC = "/tactex/touch_image"
PROMPT_TOPIC = "/tactex/operator/prompt"
PROGRESS_TOPIC = "/tactex/operator/progress"
POSE_TOPIC = "/franka_robot_state_broadcaster/current_pose"
WRENCH_TOPIC = "/franka_robot_state_broadcaster/external_wrench_in_base_frame"
TARGET_TOPIC = "/cartesian_impedance_controller/equilibrium_pose"


class CameraHealthSettings(Schema):
    """Thresholds of a camera's health on /diagnostics (ros/diagnostics.py)."""

    diag_period_s: float = param(1.0, "period of the /diagnostics status [s]", 0.1, 60.0)
    diag_rate_warn: float = param(0.8, "WARN when the measured frame rate falls below this "
                                       "fraction of the expected one", 0.0, 1.0)
    diag_rate_error: float = param(0.5, "ERROR below this fraction of the expected frame rate",
                                   0.0, 1.0)
    diag_age_warn_s: float = param(0.3, "WARN when the newest frame is older than this [s]",
                                   0.01, 60.0)
    diag_age_error_s: float = param(1.0, "ERROR when the newest frame is older than this [s]",
                                    0.01, 60.0)
    diag_drift_warn: float = param(5.0, "WARN when the no-contact frame drifted more than this "
                                        "since the start [grey levels]", 0.0, 255.0)
    diag_drift_error: float = param(15.0, "ERROR above this no-contact drift [grey levels]",
                                    0.0, 255.0)
    diag_startup_s: float = param(120.0, "start-up: no frame yet is WARN ('starting') until "
                                         "this long after configuration, then ERROR [s]",
                                  1.0, 3600.0)
    diag_pause_s: float = param(60.0, "an expected pause of the frames (the mock camera "
                                      "preparing a new placement) is WARN until this long, "
                                      "then ERROR [s]", 1.0, 3600.0)


class GelsightSettings(CameraHealthSettings):
    sensor: str = param("gelsight_mini", "sensor profile: a name from config/sensors/ "
                                         "(gelsight_mini, digit) or a path; gives the camera "
                                         "name, capture mode, crop, exposure and LED set-up")
    device: str = param("", "camera: /dev/videoN, a /dev/v4l/by-id path, a name the camera "
                            "reports (e.g. 'GelSight Mini', 'DIGIT'), a DIGIT serial number, a "
                            "video file or a folder of recorded frames ('' = the profile's "
                            "camera name)")
    fps: float = param(0.0, "frame rate to read and publish at [Hz] (0 = the profile's)",
                       0.0, 1000.0)
    warmup_frames: int = param(10, "frames dropped after opening (auto-exposure settling)",
                               0, 1000)
    reference_frames: int = param(5, "frames after warm-up averaged into the no-contact frame",
                                  1, 100)
    crop_fraction: float = param(-1.0, "fraction of each border cropped before resizing "
                                       "(< 0 = the profile's)", -1.0, 0.45)
    buffer_s: float = param(3.0, "ring buffer length [s]", 0.1, 60.0)
    frame_id: str = param("gelsight_optical_frame", "frame_id of published images")
    image_topic: str = param(IMAGE_TOPIC, "where the camera images are published")
    capture_service: str = param(CAPTURE_SERVICE, "the capture service this node serves")
    loop_file: bool = param(True, "restart a video file at its end (recordings only)")
    open_timeout_s: float = param(5.0, "deadline for opening the device [s]", 0.1, 60.0)
    capture_width: int = param(-1, "capture mode width requested from the camera [px] (-1 = "
                                   "the profile's, e.g. the GelSight SDK's 320x240; 0 = the "
                                   "camera's default)", -1, 8192)
    capture_height: int = param(-1, "capture mode height [px] (-1 = the profile's; 0 = the "
                                    "camera's default)", -1, 8192)
    auto_exposure: bool = param(False, "leave the camera's auto exposure on (off: lighting "
                                       "drift of 10 grey levels broke every strategy in "
                                       "`tactex experiment stability`); for sensors whose "
                                       "profile has exposure_controls")
    exposure: float = param(-1.0, "manual exposure in the driver's units (V4L2: 100 us) "
                                  "(< 0 = keep the value the camera has)", -1.0, 100000.0)
    auto_white_balance: bool = param(False, "leave the camera's auto white balance on")
    white_balance: float = param(-1.0, "white balance temperature [K] (< 0 = keep the "
                                       "camera's)", -1.0, 15000.0)
    led_intensity: int = param(-1, "DIGIT LED level on all channels, 0..15 (-1 = the "
                                   "profile's)", -1, 15)
    preflight: bool = param(True, "check the camera at configuration (measured frame rate, "
                                  "a sane no-contact frame) and refuse the start on a problem "
                                  "(docs/hardware_checks.md); off only for tests of the node "
                                  "itself")
    preflight_frames: int = param(25, "frames timed for the measured frame rate (cameras)",
                                  3, 1000)
    min_fps_fraction: float = param(0.8, "the measured frame rate must reach this fraction of "
                                         "the requested one", 0.0, 1.0)
    frame_min_std: float = param(5.0, "a no-contact frame whose grey-level spread is below "
                                      "this is blank (LED off, lens covered)", 0.0, 128.0)
    frame_max_saturated: float = param(0.02, "largest fraction of the no-contact frame's "
                                             "pixels at 250 or above", 0.0, 1.0)
    frame_max_texture: float = param(0.8, "a no-contact frame with more high-pass texture than "
                                          "this [grey levels] shows contact (octopi-dev: "
                                          "0.52-0.62 without contact, 0.9-2.5 for textured "
                                          "contact)", 0.0, 50.0)
    frame_max_change: float = param(0.8, "largest contact score of one reference frame "
                                         "against their mean [grey levels] (octopi-dev: "
                                         "0.31-0.38 without contact)", 0.0, 50.0)


class MotionSettings(Schema):
    scene_file: str = param("", "scene YAML (platforms, workspace, press settings)")
    robot: str = param("fr3_crisp", "robot profile: a name from config/robots/ (fr3_crisp, "
                                    "panda_crisp, sim) or a path; gives the controller, "
                                    "topics, message types, stiffness and recovery interface")
    pose_topic: str = param("", "current end-effector pose (PoseStamped) ('' = the profile's)")
    wrench_topic: str = param("", "external wrench in the base frame (WrenchStamped) "
                                  "('' = the profile's)")
    state_topic: str = param("", "franka state message topic, for profiles that read one "
                                 "('' = the profile's)")
    target_topic: str = param("", "the impedance controller's equilibrium pose topic "
                                  "('' = the profile's)")
    mode_topic: str = param("", "robot mode (reflex) topic, for profiles that read one "
                                "('' = the profile's)")
    mode_rate_hz: float = param(20.0, "robot_mode is decoded from the mode topic's full "
                                      "state (1 kHz) at most this often [Hz]", 1.0, 1000.0)
    stiffness: float = param(0.0, "the impedance controller's translational stiffness [N/m] "
                                  "(0 = the profile's)", 0.0, 1e6)
    capture_service: str = param(CAPTURE_SERVICE, "GelSight capture service")
    press_action: str = param(PRESS_ACTION, "the press action this node serves")
    result_timeout: int = param(900, "how long a press's result is kept for a client that has "
                                     "not fetched it yet [s] (rclpy ActionServer's "
                                     "result_timeout: Humble's default 900; Kilted's 10 drops "
                                     "the result of an explorer stopped longer than that)",
                                1, 86400)
    run_id: str = param("", "serve only the press goals of this run (the explorer's run_id) "
                            "('' = the run of the first goal taken; another run's are "
                            "rejected)")
    recovery_name: str = param("", "error recovery action or service ('' = the profile's)")
    recovery_timeout_s: float = param(30.0, "deadline for error recovery and re-activation, "
                                            "each call [s]", 0.5, 600.0)
    force_sign: float = param(0.0, "normal force = force_sign * wrench.force.z (0 = the "
                                   "profile's)", -1.0, 1.0)
    rate_hz: float = param(50.0, "control loop rate [Hz]", 5.0, 1000.0)
    min_contact_score: float = param(0.3, "captured frame must differ from the no-contact frame "
                                          "by at least this [grey levels], else the press is "
                                          "retried (0 = no check)", 0.0, 50.0)
    state_timeout_s: float = param(1.0, "robot state older than this aborts a press [s]",
                                   0.05, 30.0)
    state_hold_s: float = param(0.1, "robot state older than this holds the press: the "
                                     "target stays where it is until fresh state arrives "
                                     "(state_timeout_s aborts the press) [s]", 0.01, 30.0)
    preflight: bool = param(True, "check the robot at configuration, before the arm moves "
                                  "(state rate, robot mode, franka's collision thresholds) "
                                  "and refuse the start on a problem "
                                  "(docs/hardware_checks.md); off only for tests of the node "
                                  "itself")
    preflight_window_s: float = param(1.0, "robot state is counted over this window, after "
                                           "its first message [s]", 0.1, 30.0)
    preflight_deadline_s: float = param(20.0, "deadline for the first robot state message and "
                                              "for franka's collision service [s]", 0.1, 120.0)
    min_state_rate_hz: float = param(0.0, "robot state slower than this refuses the start "
                                          "[Hz] (0 = the robot profile's state.min_rate_hz, "
                                          "set from the rate its bring-up publishes at)",
                                     0.0, 10000.0)
    collision_set_by_hand: bool = param(False, "franka's collision thresholds (the robot "
                                               "profile's collision request) were set with "
                                               "the `ros2 service call` a refused start "
                                               "printed, e.g. in the bring-up before the "
                                               "controller was spawned")
    diag_period_s: float = param(1.0, "period of the /diagnostics status [s]", 0.1, 60.0)
    diag_state_warn_s: float = param(0.1, "arm: WARN when the newest robot state is older "
                                          "than this [s]", 0.01, 30.0)
    diag_state_error_s: float = param(0.5, "arm: ERROR when the newest robot state is older "
                                           "than this [s] (at most state_timeout_s, where a "
                                           "press aborts)", 0.01, 30.0)
    diag_state_rate_warn: float = param(20.0, "arm: WARN below this robot state rate [Hz]",
                                        0.0, 10000.0)
    diag_camera_topic: str = param(IMAGE_TOPIC, "camera images the press needs, watched for "
                                                "/diagnostics ('' = not watched)")
    diag_camera_warn_s: float = param(0.2, "camera link: WARN when the newest image is older "
                                           "than this [s]", 0.01, 60.0)
    diag_camera_error_s: float = param(0.5, "camera link: ERROR when the newest image is older "
                                            "than this [s] (a capture would find no fresh "
                                            "frame)", 0.01, 60.0)
    diag_startup_s: float = param(120.0, "start-up: no robot state or camera image yet is "
                                         "WARN ('starting') until this long after "
                                         "configuration, then ERROR [s]", 1.0, 3600.0)
    capture_wait_s: float = param(60.0, "a press waits this long for the camera's capture "
                                         "service before it is refused (the arm does not "
                                         "move without a camera) [s]", 0.1, 3600.0)


class ExplorerSettings(TrialSettings):
    """The explorer: a trial's settings (``config``, ``learner.*``, ``trial.*``) + the node's."""

    scene_file: str = param("", "scene YAML (platform ids and order)")
    seed: int = param(0, "seed of the learner and strategy", 0, 2**31 - 1)
    record_dir: str = param("runs/trials", "folder that receives the trial record")
    min_free_mb: float = param(50.0, "free space [MB] the record's disk must keep: checked "
                                     "before the trial and before each touch is written (a "
                                     "fuller disk ends the trial, resumable; 0 = off)",
                               0.0, 1e6)
    trial_id: str = param("", "record sub-folder ('' = time stamp)")
    resume: str = param("", "record folder of an interrupted trial to continue ('' = a new "
                            "trial); its settings must equal this node's")
    press_action: str = param(PRESS_ACTION, "press action served by the motion node")
    run_id: str = param("", "this graph's identity, sent with every press goal (a motion node "
                            "serves one run's explorer) ('' = a new one at configure)")
    state_topic: str = param(STATE_TOPIC, "where the exploration state is published after "
                                          "each decision")
    marker_topic: str = param(MARKER_TOPIC, "where the rviz markers are published")
    touch_image_topic: str = param(TOUCH_IMAGE_TOPIC, "where the latest touch image is "
                                                      "published")
    press_timeout_s: float = param(120.0, "deadline for one press (all attempts) [s]",
                                   1.0, 3600.0)
    server_timeout_s: float = param(30.0, "deadline for the press server to appear [s]",
                                    0.5, 600.0)
    press_silence_s: float = param(10.0, "a press server that sends no feedback (and no goal "
                                         "answer) for this long, or that leaves the ROS graph, "
                                         "is gone: the trial ends with that reason [s]",
                                   1.0, 600.0)
    pause_timeout_s: float = param(600.0, "a trial paused by deactivating the node ends with "
                                          "that reason when not re-activated within this [s]",
                                   1.0, 86400.0)
    goal_answer_s: float = param(2.0, "a press goal not answered within this is sent again "
                                      "(a lost goal response); the first one is followed by "
                                      "its goal id if it runs [s] (< press_silence_s)",
                                 0.1, 600.0)
    goal_renew_s: float = param(2.0, "a press goal whose every send (goal_answer_s apart, 3 "
                                     "in all) went unanswered is asked again as a new request "
                                     "once the newest has waited this long [s] (0 = never; a "
                                     "server silent for press_silence_s ends the trial first)",
                                0.0, 600.0)
    exit_when_done: bool = param(False, "shut the node down after the trial (runner, tests)")
    session_file: str = param("", "trial file of a study session (config/trials/NAME.yaml or a "
                                  "path; '' = one trial): its trials run in order in this "
                                  "node, the operator confirms each placement")
    session_dir: str = param("", "session folder ('' = record_dir/<session name>_<time>); an "
                                 "existing one of the same session is resumed where it stopped")
    trials: str = param("", "the session's trials to run now, their ids separated by commas "
                            "('' = every trial not yet done); the others stay as they are, a "
                            "later run of the session folder continues with them")
    auto_confirm: bool = param(False, "confirm each placement at once (scripted sessions, CI) "
                                      "instead of waiting for the confirm service")
    confirm_timeout_s: float = param(1800.0, "a placement not confirmed within this ends the "
                                             "session (recorded; resumable) [s]", 1.0, 86400.0)
    prompt_topic: str = param(PROMPT_TOPIC, "where the operator's instruction (what to place "
                                            "where) is published (std_msgs/String, latched)")
    diag_period_s: float = param(1.0, "period of the /diagnostics status [s]", 0.1, 60.0)
    placement_service: str = param("", "SetParameters service of a mock camera whose "
                                       "'placement' follows the session ('' = hardware: the "
                                       "operator places the fabrics)")
    nice: int = param(10, "CPU priority increment of this process, so training never starves "
                          "the control loop and the sensor (0 = unchanged)", 0, 19)
    library_materials: str = param("", "press a library instead of running trials: the "
                                       "materials, separated by commas, each placed by the "
                                       "operator and pressed library_presses times into "
                                       "library_dir/<material>/ (trial/press_library.py; "
                                       "'' = trials)")
    library_presses: int = param(10, "presses kept per material of library_materials", 1,
                                 1000)
    library_dir: str = param("", "the press library's folder (new, empty, or a press library "
                                 "to continue: only missing presses are made)")
    library_platform: str = param("", "the platform the operator places each material on "
                                      "('' = the scene's reference)")

    @model_validator(mode="after")
    def _library(self) -> ExplorerSettings:
        if self.library_materials and not self.library_dir:
            raise FieldError("library_dir", "library_materials needs the library's folder")
        if self.library_materials and self.session_file:
            raise FieldError("library_materials", "a press library and a session "
                                                  f"({self.session_file!r}) are two runs: "
                                                  "give one of them")
        return self

    @model_validator(mode="after")
    def _goal_answer(self) -> ExplorerSettings:
        if self.goal_answer_s >= self.press_silence_s:
            raise FieldError("goal_answer_s", f"{self.goal_answer_s} s must be below "
                                              f"press_silence_s ({self.press_silence_s} s): an "
                                              "unanswered goal is re-sent before the press "
                                              "server counts as silent")
        return self

    def record_inputs(self, seed: int) -> dict[str, dict]:
        """What a trial's ``config.json`` keeps of these settings with ``seed`` (a session
        trial's own): {"explorer", "learner", "trial"}; a resume compares them
        (``trial.resume.check_settings``)."""
        explorer = self.model_dump(exclude={"learner", "trial"})
        explorer["seed"] = seed
        return {"explorer": explorer, "learner": self.learner.model_dump(),
                "trial": self.trial.model_dump()}


class MockArmSettings(Schema):
    scene_file: str = param("", "scene YAML (platform surfaces)")
    robot: str = param("sim", "robot profile whose topics, target type, stiffness and wrench "
                              "sign the mock takes (PoseStamped + WrenchStamped state only)")
    pose_topic: str = param("", "where the mock publishes the current pose ('' = profile's)")
    wrench_topic: str = param("", "where the mock publishes the external wrench "
                                  "('' = profile's)")
    target_topic: str = param("", "where the mock reads equilibrium poses ('' = profile's)")
    stiffness: float = param(0.0, "impedance controller stiffness [N/m] (0 = the profile's)",
                             0.0, 1e6)
    damping: float = param(-1.0, "impedance controller damping [N s/m] (< 0 = the profile's)",
                           -1.0, 1e5)
    mass: float = param(3.0, "apparent end-effector mass [kg]", 0.1, 100.0)
    target_filter: float = param(-1.0, "controller's EMA weight kept of the filtered target "
                                       "per cycle (< 0 = the profile's)", -1.0, 0.999)
    platform_stiffness: float = param(2e4, "contact stiffness of gel, fabric and platform in "
                                           "series [N/m]", 1.0, 1e7)
    platform_damping: float = param(50.0, "contact damping [N s/m]", 0.0, 1e5)
    wrench_sign: float = param(0.0, "published wrench z = wrench_sign * contact force (0 = the "
                                    "profile's force_sign)", -1.0, 1.0)
    rate_hz: float = param(100.0, "simulation and publish rate [Hz]", 5.0, 1000.0)
    max_real_time_factor: float = param(1.0, "the fastest pace of the simulation cycles "
                                        "[cycle time per wall time] (< 1: a forced slow "
                                        "simulation, as on a starved machine)",
                                        0.001, 1.0)
    clock_every: int = param(2, "on the simulated clock, /clock goes out every this many "
                                "simulation cycles (2 at rate_hz 100: 50 Hz in 20 ms steps; "
                                "the state still at every cycle)", 1, 2)
    start_x: float = param(0.5, "start position x [m] in the base frame", -2.0, 2.0)
    start_y: float = param(0.0, "start position y [m] in the base frame", -2.0, 2.0)
    start_z: float = param(0.3, "start position z [m] in the base frame", -2.0, 2.0)
    surface_offset: float = param(0.0, "platforms' true surface z minus the scene's [m] "
                                       "(fault injection: < 0 means lower, no contact)",
                                  -0.5, 0.5)
    # the simulated world's faults (robot.mock_world.Faults; ranges and sources:
    # docs/simulated_world.md)
    wrench_offset_x: float = param(0.0, "wrench estimate bias, x [N]", -50.0, 50.0)
    wrench_offset_y: float = param(0.0, "wrench estimate bias, y [N]", -50.0, 50.0)
    wrench_offset_z: float = param(0.0, "wrench estimate bias, z [N]", -50.0, 50.0)
    offset_gradient: float = param(0.0, "the bias changes by this per metre moved from the "
                                        "start (configuration dependence) [N/m]", 0.0, 1000.0)
    wrench_drift_x: float = param(0.0, "slow drift of the bias, x [N/s]", -1.0, 1.0)
    wrench_drift_y: float = param(0.0, "slow drift of the bias, y [N/s]", -1.0, 1.0)
    wrench_drift_z: float = param(0.0, "slow drift of the bias, z [N/s]", -1.0, 1.0)
    wrench_noise: float = param(0.0, "wrench estimate noise, std per axis and sample [N]",
                                0.0, 10.0)
    static_force_x: float = param(0.0, "unmodelled static force on the arm (payload, cable), "
                                       "x [N]", -50.0, 50.0)
    static_force_y: float = param(0.0, "unmodelled static force on the arm, y [N]",
                                  -50.0, 50.0)
    static_force_z: float = param(0.0, "unmodelled static force on the arm, z, + up [N]",
                                  -50.0, 50.0)
    coulomb_friction: float = param(0.0, "Coulomb (stick-slip) friction per axis [N]",
                                    0.0, 50.0)
    viscous_friction: float = param(0.0, "viscous friction [N s/m]", 0.0, 1000.0)
    world_seed: int = param(0, "seed of the noise and of the offset's direction of change",
                            0, 2**31 - 1)
    max_stiffness: float = param(0.0, "controller clamps the stiffness here, damping still "
                                      "from the requested one (CRISP 2.3 "
                                      "variable_max_stiffness.translational: 900) [N/m] "
                                      "(0 = no clamp)", 0.0, 1e6)
    state_filter: float = param(0.0, "controller's EMA weight on the measured position and "
                                     "velocity (CRISP 2.3 filter.q / filter.dq: 0.5)",
                                0.0, 0.999)
    output_filter: float = param(0.0, "controller's EMA weight on its output force (CRISP "
                                      "2.3 filter.output_torque: 0.5)", 0.0, 0.999)
    activation_jump_x: float = param(0.0, "after each activation the controller's target is "
                                          "off by this for activation_jump_s, x [m]",
                                     -0.5, 0.5)
    activation_jump_y: float = param(0.0, "activation transient, y [m]", -0.5, 0.5)
    activation_jump_z: float = param(0.0, "activation transient, z [m]", -0.5, 0.5)
    activation_jump_s: float = param(0.0, "how long the activation transient lasts [s]",
                                     0.0, 1.0)
    reflex_force: float = param(0.0, "contact force above which the mock goes into a reflex: "
                                     "the arm stops and no state is published until recovered "
                                     "(0 = never) [N]", 0.0, 1000.0)
    reflex_limit: int = param(1, "reflexes injected at most (reflex_force)", 0, 1000)
    recovery_standin: Literal["none", "action", "service"] = param("none", "serve stand-ins of the recovery interfaces: 'action' "
                                          "(tactex/action/Press as the action type), 'service' "
                                          "(std_srvs/srv/Trigger), plus the re-activation "
                                          "services (std_srvs/srv/SetBool) for tests")
    recovery_name: str = param("/tactex_test/error_recovery", "stand-in recovery name")
    hardware_service: str = param("/tactex_test/set_hardware_active",
                                  "stand-in hardware re-activation service (SetBool)")
    controller_service: str = param("/tactex_test/activate_controller",
                                    "stand-in controller re-activation service (SetBool)")
    diag_period_s: float = param(1.0, "period of the /diagnostics status [s]", 0.1, 60.0)


class MockImageSettings(CameraHealthSettings):
    scene_file: str = param("", "scene YAML (what lies on each platform: sim_fabric or "
                                "replay_class)")
    source: str = param("sim", "sim[:difficulty] or replay:DIR")
    pose_topic: str = param(POSE_TOPIC, "mock arm pose, to know what is under the sensor")
    wrench_topic: str = param(WRENCH_TOPIC, "mock arm external wrench, to know the contact "
                                            "force")
    image_topic: str = param(IMAGE_TOPIC, "where the rendered images are published")
    capture_service: str = param(CAPTURE_SERVICE, "the capture service this node serves")
    fps: float = param(25.0, "published frame rate [Hz]", 1.0, 120.0)
    depth_per_n: float = param(0.1, "gel indentation [mm] per newton of contact force (the "
                                    "GelSight Mini's gel takes about 0.4 mm at 4 N)", 0.0, 10.0)
    buffer_s: float = param(3.0, "ring buffer length [s]", 0.1, 60.0)
    frame_id: str = param("gelsight_optical_frame", "frame_id of published images")
    seed: int = param(0, "seed of the rendered presses", 0, 2**31 - 1)
    fault_blank: float = param(0.0, "probability that a press shows no texture (fault "
                                    "injection)", 0.0, 1.0)
    placement: str = param("", "what lies on each platform, 'platform=fabric,...' over the "
                               "scene's sim_fabric ('' = the scene's); may be set while "
                               "running (a study session sets it before each trial)")
