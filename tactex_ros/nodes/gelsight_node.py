"""gelsight_node: the GelSight Mini as a ROS 2 camera with a capture service.

Opens the sensor with OpenCV by device path (``/dev/videoN``, ``/dev/v4l/by-id/...``), by the
name the camera reports (``GelSight Mini`` under /sys/class/video4linux/*/name), or a video
file (recordings; tests use octopi-dev presses). Drops ``warmup_frames``, averages the next
``reference_frames`` into the no-contact frame, crops ``crop_fraction`` of each border and
resizes to 320x240, publishes ``sensor_msgs/Image`` rgb8 on /tactex/gelsight/image_raw
(sensor-data QoS, stamped, frame_id set), keeps a ring buffer of ``buffer_s`` seconds and serves
/tactex/gelsight/capture with the strongest-contact frame. Frames are read in their own thread.

A camera (not a file) is set up through OpenCV's V4L2 properties before the warm-up: the
capture mode (``capture_width`` x ``capture_height``, the SDK's 320x240), auto exposure and
auto white balance off (``exposure`` / ``white_balance`` fix their values where given), so the
no-contact reference stays valid for the whole trial. A property the driver refuses ends the
configuration with the parameter named; the values read back are logged. The measured frame
rate is logged every 10 s (``measured_fps``).
"""

from __future__ import annotations

import glob
import re
import threading
import time
from pathlib import Path

import cv2
import numpy as np
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from .. import adapter
from ..core.contact import FrameRing, crop_border
from ..core.errors import TactexError
from ..node_settings import GelsightSettings
from .capture import serve_capture
from .common import TactexNode, run


def resolve_device(device: str) -> tuple[str, bool]:
    """(path to open, is_file) for a device path, by-id path, camera name or video file."""
    if not device:
        raise TactexError("gelsight device: empty; give /dev/videoN, a /dev/v4l/by-id path, "
                          "the camera's name or a video file")
    p = Path(device)
    if p.exists():
        return str(p.resolve() if str(p).startswith("/dev/v4l") else p), p.is_file()
    for name_file in sorted(glob.glob("/sys/class/video4linux/video*/name"), key=_video_number):
        if Path(name_file).read_text().strip().lower().startswith(device.lower()):
            return "/dev/" + Path(name_file).parent.name, False
    for link in sorted(glob.glob("/dev/v4l/by-id/*")):
        if device.lower().replace(" ", "_") in Path(link).name.lower():
            return str(Path(link).resolve()), False
    raise TactexError(f"gelsight device {device!r}: no such file and no camera reports that "
                      "name (/sys/class/video4linux/*/name, /dev/v4l/by-id)")


def _video_number(path: str) -> tuple[int, str]:
    """Sort key: /sys/class/video4linux/video10 after video9 (numeric, not lexicographic)."""
    m = re.search(r"/video(\d+)(?:/|$)", path)
    return (int(m.group(1)) if m else 1 << 30, path)


# OpenCV's V4L2 backend: CAP_PROP_AUTO_EXPOSURE 1 = manual, 3 = aperture priority (auto)
V4L2_EXPOSURE_MANUAL, V4L2_EXPOSURE_AUTO = 1.0, 3.0


def camera_setup(cap, s) -> dict[str, float]:
    """Apply capture mode, exposure and white balance to an opened ``cv2.VideoCapture`` (V4L2).

    ``s``: GelsightSettings. Returns the values read back; TactexError names the parameter
    whose property the driver refused."""
    wanted: list[tuple[str, int, float]] = []
    if s.capture_width and s.capture_height:
        wanted += [("capture_width", cv2.CAP_PROP_FRAME_WIDTH, float(s.capture_width)),
                   ("capture_height", cv2.CAP_PROP_FRAME_HEIGHT, float(s.capture_height))]
    wanted.append(("auto_exposure", cv2.CAP_PROP_AUTO_EXPOSURE,
                   V4L2_EXPOSURE_AUTO if s.auto_exposure else V4L2_EXPOSURE_MANUAL))
    if not s.auto_exposure and s.exposure >= 0:
        wanted.append(("exposure", cv2.CAP_PROP_EXPOSURE, float(s.exposure)))
    wanted.append(("auto_white_balance", cv2.CAP_PROP_AUTO_WB,
                   1.0 if s.auto_white_balance else 0.0))
    if not s.auto_white_balance and s.white_balance >= 0:
        wanted.append(("white_balance", cv2.CAP_PROP_WB_TEMPERATURE, float(s.white_balance)))
    got = {}
    for name, prop, value in wanted:
        if not cap.set(prop, value):
            raise TactexError(f"gelsight {name} = {value:g}: the camera driver refused it "
                              "(v4l2-ctl --list-ctrls shows what the camera supports)")
        got[name] = float(cap.get(prop))
    if s.capture_width and s.capture_height and \
            (got["capture_width"], got["capture_height"]) != (s.capture_width, s.capture_height):
        raise TactexError(f"gelsight capture_width x capture_height = {s.capture_width}x"
                          f"{s.capture_height}: the camera runs "
                          f"{got['capture_width']:g}x{got['capture_height']:g}")
    return got


class GelsightNode(TactexNode):
    settings_cls = GelsightSettings

    def __init__(self, **kw) -> None:
        super().__init__("gelsight", **kw)

    def configure(self) -> None:
        s = self.settings
        self.path, self.is_file = resolve_device(s.device)
        self.cap = cv2.VideoCapture(self.path) if self.is_file else \
            cv2.VideoCapture(self.path, cv2.CAP_V4L2)
        end = time.monotonic() + s.open_timeout_s
        while not self.cap.isOpened():
            if time.monotonic() > end:
                raise TactexError(f"gelsight device {s.device!r} ({self.path}): could not be "
                                  f"opened within open_timeout_s ({s.open_timeout_s} s)")
            time.sleep(0.1)
            self.cap.open(self.path)
        if not self.is_file:
            self.camera = camera_setup(self.cap, s)
            self.get_logger().info(f"gelsight camera settings: {self.camera}")
        self.ring = FrameRing(max(2, int(round(s.buffer_s * s.fps))))
        self.lock = threading.Lock()
        self.pub = self.create_lifecycle_publisher(Image, s.image_topic, qos_profile_sensor_data)
        serve_capture(self, self.ring, self.lock, s.frame_id, s.capture_service)
        self.frames_read = 0
        self.measured_fps = 0.0
        self._stop = threading.Event()
        self._warm = False            # warm-up frames dropped (once per configuration)
        self._refs: list[np.ndarray] = []

    def activate(self) -> None:
        self._stop.clear()
        self.reader = threading.Thread(target=self._read_loop, name="gelsight", daemon=True)
        self.reader.start()

    def deactivate(self) -> None:
        """Stop reading: the reader thread ends within a frame (joined with a deadline)."""
        self._stop.set()
        reader = getattr(self, "reader", None)
        if reader is not None:
            reader.join(timeout=max(1.0, 3.0 / self.settings.fps))
            if reader.is_alive():
                self.get_logger().warning("gelsight reader did not stop within its deadline")

    def cleanup(self) -> None:
        """Release the camera (or video file)."""
        cap = getattr(self, "cap", None)
        if cap is not None:
            cap.release()
            self.cap = None

    def _read(self) -> np.ndarray | None:
        ok, bgr = self.cap.read()
        if not ok and self.is_file and self.settings.loop_file:
            self.cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, bgr = self.cap.read()
        if not ok or bgr is None or bgr.ndim != 3:
            return None
        return np.ascontiguousarray(crop_border(bgr, self.settings.crop_fraction)[:, :, ::-1])

    def _read_loop(self) -> None:
        s = self.settings
        period = 1.0 / s.fps
        if not self._warm:
            for _ in range(s.warmup_frames):
                self.cap.read()
            self._warm = True
        refs = self._refs
        next_t = time.monotonic()
        misses = 0
        t_rate, n_rate = time.monotonic(), 0
        while not self._stop.is_set():
            frame = self._read()
            if frame is None:
                misses += 1
                if self.is_file or misses > s.fps * s.open_timeout_s:
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
                                       f"(requested {s.fps:g})")
            if len(refs) < s.reference_frames:
                refs.append(frame.astype(np.float32))
                if len(refs) == s.reference_frames:
                    with self.lock:
                        self.ring.set_reference(np.mean(refs, axis=0).round().astype(np.uint8))
            now = self.get_clock().now().nanoseconds * 1e-9
            with self.lock:
                self.ring.push(now, frame)
            self.pub.publish(adapter.array_to_image(frame, now, s.frame_id))
            if self.is_file:  # a recording plays at its nominal rate
                next_t += period
                time.sleep(max(0.0, next_t - time.monotonic()))


def main(args: list[str] | None = None) -> int:
    return run(GelsightNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
