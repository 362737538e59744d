"""gelsight_node: a vision-based tactile sensor as a ROS 2 camera with a capture service.

The sensor is a profile (``sensor``: ``config/sensors/<name>.yaml``, see
``tactex_ros/robot/sensors.py``): ``gelsight_mini`` (default) or ``digit``. Opens the camera with
OpenCV by device path (``/dev/videoN``, ``/dev/v4l/by-id/...``), by the name the camera
reports (``GelSight Mini``, ``DIGIT`` under /sys/class/video4linux/*/name, in numeric device
order), by a DIGIT serial number (digit-interface's ``DigitHandler.find_digit`` where that
package is installed, else its by-id link), or plays a recording: a video file, or a folder
of frames (PNG/JPEG/BMP in natural file-name order). Drops ``warmup_frames``, averages the
next ``reference_frames`` into the no-contact frame, crops the profile's ``crop_fraction`` of
each border and resizes to 320x240, publishes ``sensor_msgs/Image`` rgb8 on
/tactex/gelsight/image_raw (sensor-data QoS, stamped, frame_id set), keeps a ring buffer of
``buffer_s`` seconds and serves /tactex/gelsight/capture with the strongest-contact frame.
Frames are read in their own thread.

A camera (not a recording) is set up through OpenCV's V4L2 properties before the warm-up: the
capture mode (one of the profile's modes where it lists them, with its frame rate), auto
exposure and auto white balance off for sensors that have them (``exposure`` /
``white_balance`` fix their values where given), a DIGIT's LED level. A property the driver
refuses ends the configuration with the parameter named; the values read back are logged. The
measured frame rate is logged every 10 s (``measured_fps``).

The configuration reads the warm-up frames and the no-contact (reference) frames itself, and
with ``preflight`` (default) checks them before the graph goes on (``robot/preflight.py``): a
camera's frame rate measured over ``preflight_frames`` frames reaches ``min_fps_fraction`` of
the requested one, and the no-contact frame is not blank, not saturated, shows no contact and
is steady. A problem refuses the configuration with the reason (exit status 2).
"""

from __future__ import annotations

import glob
import re
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from .. import adapter
from ...core.contact import crop_border
from ...core.errors import DeviceError, InputError
from ..settings import GelsightSettings
from ...robot import preflight as checks
from ...robot.frames import FrameRing
from ...robot.sensors import (SensorConfig, SensorProfile, digit_led_value, load_sensor,
                              sensor_config)
from .capture import serve_capture
from .lifecycle import TactexNode
from .process import run


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


@dataclass
class Device:
    """What ``resolve_device`` found: ``path`` to open, ``kind`` (camera, file, folder) and,
    for a DIGIT found through digit-interface, its firmware ``revision``."""

    path: str
    kind: str
    revision: int | None = None

    @property
    def recording(self) -> bool:
        return self.kind != "camera"


def resolve_device(device: str, serial_lookup: str = "") -> Device:
    """The device for a path, by-id path, camera name, serial number, video file or folder of
    frames; ``serial_lookup`` ``digit_interface``: ask digit-interface (where installed)."""
    if not device:
        raise InputError("gelsight device: empty; give /dev/videoN, a /dev/v4l/by-id path, "
                         "the camera's name, a serial number, a video file or a folder")
    p = Path(device)
    if p.exists():
        if p.is_dir():
            return Device(str(p), "folder")
        if p.is_file():
            return Device(str(p), "file")
        return Device(str(p.resolve() if str(p).startswith("/dev/v4l") else p), "camera")
    hint = ""
    if serial_lookup == "digit_interface":
        found, hint = _digit_by_serial(device)
        if found is not None:
            return found
    for name_file in sorted(glob.glob("/sys/class/video4linux/video*/name"), key=_video_number):
        if Path(name_file).read_text().strip().lower().startswith(device.lower()):
            return Device("/dev/" + Path(name_file).parent.name, "camera")
    for link in sorted(glob.glob("/dev/v4l/by-id/*")):
        if device.lower().replace(" ", "_") in Path(link).name.lower():
            return Device(str(Path(link).resolve()), "camera")
    raise DeviceError(f"gelsight device {device!r}: no such file and no camera reports that "
                      f"name (/sys/class/video4linux/*/name, /dev/v4l/by-id){hint}; is the "
                      "camera plugged in?")


def _digit_by_serial(serial: str) -> tuple[Device | None, str]:
    """(the DIGIT with this serial via digit-interface, or None; a hint for the error)."""
    try:
        from digit_interface import DigitHandler
    except ImportError:
        return None, ("; digit-interface is not installed, so serial numbers are looked up "
                      "only in /dev/v4l/by-id")
    try:
        found = DigitHandler.find_digit(serial)
    except Exception as exc:  # noqa: BLE001 - udev unavailable (container, no libudev)
        return None, f"; digit-interface could not list DIGITs ({type(exc).__name__}: {exc})"
    if not found:
        return None, "; digit-interface lists no DIGIT with that serial"
    try:
        revision = int(found.get("revision", ""))
    except ValueError:
        revision = None
    return Device(str(found["dev_name"]), "camera", revision), ""


def _video_number(path: str) -> tuple[int, str]:
    """Sort key: /sys/class/video4linux/video10 after video9 (numeric, not lexicographic)."""
    m = re.search(r"/video(\d+)(?:/|$)", path)
    return (int(m.group(1)) if m else 1 << 30, path)


def _natural(path: Path) -> list:
    """Sort key: frame_2.png before frame_10.png."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


class FrameFolder:
    """A folder of recorded frames read like a ``cv2.VideoCapture`` (read, set position)."""

    def __init__(self, folder: str) -> None:
        self.files = sorted((f for f in Path(folder).iterdir()
                             if f.suffix.lower() in IMAGE_SUFFIXES), key=_natural)
        if not self.files:
            raise InputError(f"gelsight device {folder!r}: a folder without frames "
                             f"({'/'.join(IMAGE_SUFFIXES)})")
        bad = [f.name for f in self.files if not cv2.haveImageReader(str(f))]
        if bad:
            raise InputError(f"gelsight recording {folder!r}: not readable as images: {bad[:5]}")
        self.pos = 0

    def isOpened(self) -> bool:  # noqa: N802 - cv2.VideoCapture's name
        return True

    def open(self, _path: str) -> bool:
        return True

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self.pos >= len(self.files):
            return False, None
        f = self.files[self.pos]
        self.pos += 1
        bgr = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if bgr is None:
            raise InputError(f"gelsight recording: {str(f)!r} is not a readable image")
        return True, bgr

    def set(self, prop: int, value: float) -> bool:
        if prop != cv2.CAP_PROP_POS_FRAMES:
            return False
        self.pos = int(value)
        return True

    def release(self) -> None:
        pass


def landscape(bgr: np.ndarray, prof: SensorProfile) -> np.ndarray:
    """A recorded frame in a profile mode's transposed size (digit-interface's ``get_frame()``
    turns DIGIT frames 90 degrees counter-clockwise) turned back to the sensor's landscape."""
    h, w = bgr.shape[:2]
    if prof.portrait_recordings and h > w and \
            any((m.width, m.height) == (h, w) for m in prof.modes):
        return cv2.rotate(bgr, cv2.ROTATE_90_CLOCKWISE)
    return bgr


# OpenCV's V4L2 backend: CAP_PROP_AUTO_EXPOSURE 1 = manual, 3 = aperture priority (auto)
V4L2_EXPOSURE_MANUAL, V4L2_EXPOSURE_AUTO = 1.0, 3.0


def camera_setup(cap, cfg: SensorConfig, revision: int | None = None) -> dict[str, float]:
    """Apply capture mode (and its frame rate where the profile lists modes), exposure, white
    balance and a DIGIT's LED level to an opened ``cv2.VideoCapture`` (V4L2). Returns the
    values read back; InputError names the parameter whose property the driver refused."""
    wanted: list[tuple[str, int, float]] = []
    if cfg.capture_width and cfg.capture_height:
        wanted += [("capture_width", cv2.CAP_PROP_FRAME_WIDTH, float(cfg.capture_width)),
                   ("capture_height", cv2.CAP_PROP_FRAME_HEIGHT, float(cfg.capture_height))]
        if cfg.profile.modes:
            wanted.append(("fps", cv2.CAP_PROP_FPS, float(cfg.fps)))
    if cfg.profile.exposure_controls:
        wanted.append(("auto_exposure", cv2.CAP_PROP_AUTO_EXPOSURE,
                       V4L2_EXPOSURE_AUTO if cfg.auto_exposure else V4L2_EXPOSURE_MANUAL))
        if not cfg.auto_exposure and cfg.exposure >= 0:
            wanted.append(("exposure", cv2.CAP_PROP_EXPOSURE, float(cfg.exposure)))
        wanted.append(("auto_white_balance", cv2.CAP_PROP_AUTO_WB,
                       1.0 if cfg.auto_white_balance else 0.0))
        if not cfg.auto_white_balance and cfg.white_balance >= 0:
            wanted.append(("white_balance", cv2.CAP_PROP_WB_TEMPERATURE,
                           float(cfg.white_balance)))
    if cfg.led_intensity is not None:
        wanted.append(("led_intensity", cv2.CAP_PROP_ZOOM,
                       float(digit_led_value(cfg.led_intensity, revision))))
    got = {}
    for name, prop, value in wanted:
        if not cap.set(prop, value):
            raise InputError(f"gelsight {name} = {value:g}: the camera driver refused it "
                             "(v4l2-ctl --list-ctrls shows what the camera supports)")
        got[name] = float(cap.get(prop))
    if cfg.capture_width and cfg.capture_height and \
            (got["capture_width"], got["capture_height"]) != (cfg.capture_width,
                                                              cfg.capture_height):
        raise InputError(f"gelsight capture_width x capture_height = {cfg.capture_width}x"
                         f"{cfg.capture_height}: the camera runs "
                         f"{got['capture_width']:g}x{got['capture_height']:g}")
    return got


class GelsightNode(TactexNode):
    settings_cls = GelsightSettings

    def __init__(self, **kw) -> None:
        super().__init__("gelsight", **kw)

    def configure(self) -> None:
        s = self.settings
        prof = load_sensor(s.sensor)
        self.device = resolve_device(s.device or prof.device, prof.serial_lookup)
        cfg = self.cfg = sensor_config(s, camera=not self.device.recording)
        self.is_file = self.device.recording
        path = self.device.path
        if self.device.kind == "folder":
            self.cap = FrameFolder(path)
        else:
            self.cap = cv2.VideoCapture(path) if self.is_file else \
                cv2.VideoCapture(path, cv2.CAP_V4L2)
        end = time.monotonic() + s.open_timeout_s
        while not self.cap.isOpened():
            if time.monotonic() > end:
                raise DeviceError(f"gelsight device {cfg.device!r} ({path}): could not be "
                                  f"opened within open_timeout_s ({s.open_timeout_s} s)")
            time.sleep(0.1)
            self.cap.open(path)
        if not self.is_file:
            self.camera = camera_setup(self.cap, cfg, self.device.revision)
            self.get_logger().info(f"{cfg.profile.name} camera settings: {self.camera}")
        self.ring = FrameRing(max(2, int(round(s.buffer_s * cfg.fps))))
        self.lock = threading.Lock()
        self.pub = self.create_lifecycle_publisher(Image, s.image_topic, qos_profile_sensor_data)
        serve_capture(self, self.ring, self.lock, s.frame_id, s.capture_service)
        from ..diagnostics import CameraHealth, Diagnostics
        self.health = CameraHealth(cfg.fps, s)
        self.diag = Diagnostics(self, s.diag_period_s)
        self.diag.add("camera", f"{cfg.profile.name} {self.device.path}", self.health.check)
        self.frames_read = 0
        self.measured_fps = 0.0
        self._stop = threading.Event()
        self._no_contact_frame()

    def _no_contact_frame(self) -> None:
        """Drop the warm-up frames, read the reference frames (a camera: at least
        ``preflight_frames``, timed), average the last ``reference_frames`` into the no-contact
        frame; with ``preflight``, refuse (InputError) a slow camera or an insane frame."""
        s = self.settings
        for _ in range(s.warmup_frames):
            self.cap.read()
        n = s.reference_frames if self.is_file else max(s.reference_frames, s.preflight_frames)
        frames, stamps = [], []
        end = time.monotonic() + s.open_timeout_s + n / self.cfg.fps
        while len(frames) < n:
            if time.monotonic() > end:
                raise checks.Problem(
                    "no_frame", f"only {len(frames)} of {n} frames read within "
                                f"{s.open_timeout_s + n / self.cfg.fps:.1f} s").error()
            frame = self._read_frame()
            if frame is not None:
                frames.append(frame)
                stamps.append(time.monotonic())
        refs = frames[-s.reference_frames:]
        if s.preflight:
            problem = None if self.is_file else checks.fps_problem(stamps, self.cfg.fps,
                                                                 s.min_fps_fraction)
            problem = problem or checks.frame_problem(refs, checks.FrameLimits(
                s.frame_min_std, s.frame_max_saturated, s.frame_max_texture,
                s.frame_max_change))
            if problem:
                raise InputError(str(problem))
            self.get_logger().info(
                "pre-flight: camera " + ("(recording: frame rate not measured)" if self.is_file
                                         else f"{checks.rate_hz(stamps):.1f} frames/s")
                + f", no-contact frame texture {checks.texture(refs[0]):.2f}")
        else:
            self.get_logger().warning("pre-flight off (preflight: false): frame rate and "
                                      "no-contact frame not checked")
        with self.lock:
            self.ring.set_reference(np.mean([f.astype(np.float32) for f in refs], axis=0)
                                    .round().astype(np.uint8))

    def activate(self) -> None:
        self._stop.clear()
        self.reader = threading.Thread(target=self._read_loop, name="gelsight", daemon=True)
        self.reader.start()

    def deactivate(self) -> None:
        """Stop reading before the publisher goes off (a publish racing rclpy's shutdown aborted
        the process at 60 fps): the reader thread ends within a frame (joined, deadline)."""
        self._stop.set()
        reader = getattr(self, "reader", None)
        if reader is not None and reader is not threading.current_thread():
            reader.join(timeout=max(2.0, 3.0 / self.cfg.fps))
            if reader.is_alive():
                self.get_logger().warning("gelsight reader did not stop within its deadline")

    def cleanup(self) -> None:
        """Release the camera (or video file)."""
        cap = getattr(self, "cap", None)
        if cap is not None:
            cap.release()
            self.cap = None

    def _read(self) -> np.ndarray | None:
        try:
            return self._read_frame()
        except InputError as exc:     # a recorded frame that does not decode
            self.get_logger().error(str(exc))
            return None

    def _read_frame(self) -> np.ndarray | None:
        ok, bgr = self.cap.read()
        if not ok and self.is_file and self.settings.loop_file:
            self.cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, bgr = self.cap.read()
        if not ok or bgr is None or bgr.ndim != 3:
            return None
        if self.is_file:
            bgr = landscape(bgr, self.cfg.profile)
        return np.ascontiguousarray(crop_border(bgr, self.cfg.crop_fraction)[:, :, ::-1])

    def _read_loop(self) -> None:
        s = self.settings
        period = 1.0 / self.cfg.fps
        next_t = time.monotonic()
        misses = 0
        t_rate, n_rate = time.monotonic(), 0
        while not self._stop.is_set():
            frame = self._read()
            if frame is None:
                misses += 1
                if self.is_file or misses > self.cfg.fps * s.open_timeout_s:
                    self.get_logger().warning("gelsight: no more frames")
                    return
                continue
            misses = 0
            self.frames_read += 1
            n_rate += 1
            if time.monotonic() - t_rate >= 10.0:
                self.measured_fps = n_rate / (time.monotonic() - t_rate)
                t_rate, n_rate = time.monotonic(), 0
                self.get_logger().info(f"gelsight frame rate {self.measured_fps:.1f} Hz "
                                       f"(requested {self.cfg.fps:g})")
            now = self.get_clock().now().nanoseconds * 1e-9
            with self.lock:
                self.ring.push(now, frame)
            self.pub.publish(adapter.array_to_image(frame, now, s.frame_id))
            self.health.observe(frame)
            if self.is_file:  # a recording plays at its nominal rate
                next_t += period
                time.sleep(max(0.0, next_t - time.monotonic()))


def main(args: list[str] | None = None) -> int:
    return run(GelsightNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
