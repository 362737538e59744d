"""Sensor profiles for the camera node (``config/sensors/<name>.yaml``): what a vision-based
tactile sensor is and how it is set up; validated once, every error names the field.

Pure Python (no rclpy, no OpenCV). A profile says:

- ``device``: the name the camera reports (``/sys/class/video4linux/*/name``), used when the
  node's ``device`` parameter is empty;
- ``serial_lookup``: ``digit_interface`` finds a device given by serial number (e.g.
  ``D20001``) with digit-interface's ``DigitHandler.find_digit`` where that package is
  installed (it also gives the firmware revision, which decides the LED encoding); ``""``: no
  serial lookup (a ``/dev/v4l/by-id`` link that contains the serial still works);
- ``modes``: the capture modes the sensor offers (``width``, ``height`` [px], ``fps`` list);
  empty: not checked here (the driver's read-back is);
- ``capture``: the mode used (``width``, ``height``, ``fps``), one of ``modes`` when listed;
- ``crop_fraction``: border cut before the frame is resized to 320x240;
- ``exposure_controls``: the node switches auto exposure and auto white balance off through
  V4L2 (the GelSight Mini has them; digit-interface sets neither on a DIGIT);
- ``led_intensity``: DIGIT LED level 0..15 set on all three channels (null: not set);
- ``portrait_recordings``: recorded frames in the transposed mode (height x width swapped, as
  digit-interface's ``get_frame()`` returns them by default) are turned back to landscape.

``sensor_config`` merges a profile with the node's parameters (a parameter left at its
"profile's" value takes the profile's).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import Field, StringConstraints

from ..core.schema import Schema, param
from ..core.errors import InputError
from ..core.paths import config_file, read_yaml

SERIAL_LOOKUPS = ("", "digit_interface")
LED_MAX = 15


@dataclass(frozen=True)
class Mode:
    width: int
    height: int
    fps: tuple[float, ...]


@dataclass(frozen=True)
class SensorProfile:
    name: str
    device: str
    capture_width: int
    capture_height: int
    fps: float
    crop_fraction: float
    modes: tuple[Mode, ...] = ()
    serial_lookup: str = ""
    exposure_controls: bool = True
    led_intensity: int | None = None
    portrait_recordings: bool = False
    notes: str = ""

    def mode_text(self) -> str:
        return ", ".join(f"{m.width}x{m.height} at {'/'.join(f'{f:g}' for f in m.fps)} fps"
                         for m in self.modes)


@dataclass(frozen=True)
class SensorConfig:
    """A profile with the node's parameters applied: what the node opens and sets."""

    profile: SensorProfile
    device: str
    capture_width: int          # 0: the camera's default mode
    capture_height: int
    fps: float
    crop_fraction: float
    auto_exposure: bool
    exposure: float
    auto_white_balance: bool
    white_balance: float
    led_intensity: int | None


Rate = Annotated[float, Field(ge=1, le=1000)]


class ModeSpec(Schema):
    width: int = param(..., "px", 1, 8192)
    height: int = param(..., "px", 1, 8192)
    fps: list[Rate] = param(..., "frame rates [Hz]", min_length=1)


class CaptureSpec(Schema):
    width: int = param(..., "px (0 with height 0: the camera's default mode)", 0, 8192)
    height: int = param(..., "px", 0, 8192)
    fps: float = param(..., "frame rate [Hz]", 1, 1000)


class SensorFile(Schema):
    """A sensor profile file (``config/sensors/<name>.yaml``) as written."""

    name: Annotated[str, StringConstraints(min_length=1)] = param(..., "profile name")
    device: Annotated[str, StringConstraints(min_length=1)] = param(
        ..., "the name the camera reports")
    serial_lookup: Literal[SERIAL_LOOKUPS] = param("", "how a serial number finds the device")
    modes: list[ModeSpec] = param([], "the capture modes the sensor offers")
    capture: CaptureSpec
    crop_fraction: float = param(..., "border cut before the resize", 0.0, 0.45)
    exposure_controls: bool = param(True, "auto exposure / white balance switched off")
    led_intensity: int | None = param(None, "DIGIT LED level", 0, LED_MAX)
    portrait_recordings: bool = param(False, "recorded frames are transposed")
    notes: str = param("", "free text")


def parse_sensor(data: Any, origin: str = "sensor profile") -> SensorProfile:
    """Validate a sensor profile mapping; InputError names every bad field (``modes.0.fps``,
    ``capture``)."""
    f = SensorFile.check(data, origin)
    cap = f.capture
    prof = SensorProfile(
        name=f.name, device=f.device, capture_width=cap.width, capture_height=cap.height,
        fps=float(cap.fps), crop_fraction=float(f.crop_fraction),
        modes=tuple(Mode(m.width, m.height, tuple(float(r) for r in m.fps)) for m in f.modes),
        serial_lookup=f.serial_lookup, exposure_controls=f.exposure_controls,
        led_intensity=f.led_intensity, portrait_recordings=f.portrait_recordings,
        notes=f.notes)
    check_mode(prof, cap.width, cap.height, prof.fps, f"{origin}: capture")
    return prof


def check_mode(prof: SensorProfile, width: int, height: int, fps: float, where: str) -> None:
    """Refuse a capture mode the sensor does not offer (when its profile lists modes)."""
    if not prof.modes or (width, height) == (0, 0):
        return
    if not any((m.width, m.height) == (width, height) and fps in m.fps for m in prof.modes):
        raise InputError(f"{where}: {width}x{height} at {fps:g} fps is not a mode of sensor "
                         f"{prof.name!r} ({prof.mode_text()})")


def load_sensor(name_or_path: str) -> SensorProfile:
    """Read and validate a sensor profile by name (``config/sensors/``) or path."""
    p = config_file(name_or_path, "sensors", "sensor profile")
    return parse_sensor(read_yaml(p, "sensor profile"), origin=f"sensor profile {p.name}")


def sensor_config(s: Any, camera: bool = True) -> SensorConfig:
    """The node's settings (``GelsightSettings``) over its sensor profile: ``device`` ''
    -> the profile's camera name, ``capture_width``/``capture_height`` -1, ``fps`` 0,
    ``crop_fraction`` < 0 and ``led_intensity`` -1 -> the profile's. For a ``camera`` (not a
    recording) a capture mode the sensor does not offer is refused, the parameters named."""
    prof = load_sensor(s.sensor)
    cw = prof.capture_width if s.capture_width < 0 else s.capture_width
    ch = prof.capture_height if s.capture_height < 0 else s.capture_height
    if (cw == 0) != (ch == 0):
        raise InputError(f"gelsight capture_width x capture_height = {cw}x{ch}: give both or "
                         "neither (0 = the camera's default mode)")
    fps = s.fps or prof.fps
    if camera:
        check_mode(prof, cw, ch, fps, "gelsight capture_width x capture_height at fps")
    led = prof.led_intensity if s.led_intensity < 0 else int(s.led_intensity)
    if led is not None and not 0 <= led <= LED_MAX:
        raise InputError(f"gelsight led_intensity: 0..{LED_MAX}, got {led}")
    return SensorConfig(
        profile=prof, device=s.device or prof.device, capture_width=cw, capture_height=ch,
        fps=fps, crop_fraction=prof.crop_fraction if s.crop_fraction < 0 else s.crop_fraction,
        auto_exposure=s.auto_exposure, exposure=s.exposure,
        auto_white_balance=s.auto_white_balance, white_balance=s.white_balance,
        led_intensity=led)


def digit_led_value(level: int, revision: int | None) -> int:
    """The UVC zoom-control value that sets a DIGIT's three LEDs to ``level`` (0..15), as
    digit-interface 0.2.1 encodes it (R << 8 | G << 4 | B) for firmware revision >= 200; an
    older firmware (1.01, no per-channel control) is refused. ``revision`` None: unknown (no
    digit-interface), taken as current firmware."""
    if not 0 <= level <= LED_MAX:
        raise InputError(f"DIGIT led_intensity: 0..{LED_MAX}, got {level}")
    if revision is not None and revision < 200:
        raise InputError(f"DIGIT firmware revision {revision}: no per-channel LED control "
                         "(digit-interface deprecates it); update the firmware or give the "
                         "sensor profile led_intensity: null")
    return (level << 8) | (level << 4) | level
