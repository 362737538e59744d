"""Sensor profiles (config/sensors, tactex_ros/robot/sensors.py) and the camera node's DIGIT path
without a sensor: modes, LED encoding, serial lookup through a digit-interface stand-in,
recorded frame folders and their orientation."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_ros.core.errors import DeviceError, InputError
from tactex_ros.ros.settings import GelsightSettings
from tactex_ros.ros.nodes.gelsight_node import (FrameFolder, camera_setup, landscape,
                                            resolve_device)
from tactex_ros.core.paths import config_names
from tactex_ros.robot.sensors import digit_led_value, load_sensor, parse_sensor, sensor_config

from test_gelsight_setup import RecordingCapture


def test_shipped_profiles() -> None:
    assert {"gelsight_mini", "digit"} <= set(config_names("sensors"))
    g = load_sensor("gelsight_mini")
    assert (g.capture_width, g.capture_height, g.crop_fraction) == (320, 240, 0.15)
    assert g.exposure_controls and g.led_intensity is None
    d = load_sensor("digit")
    # digit-interface 0.2.1's Digit.STREAMS
    assert {(m.width, m.height, m.fps) for m in d.modes} == {(320, 240, (60.0, 30.0)),
                                                              (640, 480, (30.0, 15.0))}
    assert (d.capture_width, d.capture_height, d.fps) == (320, 240, 60.0)
    assert d.serial_lookup == "digit_interface" and not d.exposure_controls
    assert d.led_intensity == 15 and d.portrait_recordings


def test_modes_match_digit_interface_where_installed() -> None:
    di = pytest.importorskip("digit_interface", reason="digit-interface is not installed "
                             "(optional; pip install --no-deps digit-interface pyudev)")
    d = load_sensor("digit")
    streams = {(v["resolution"]["width"], v["resolution"]["height"],
                tuple(sorted(float(f) for f in v["fps"].values())))
               for v in di.Digit.STREAMS.values()}
    assert streams == {(m.width, m.height, tuple(sorted(m.fps))) for m in d.modes}


def _digit_data() -> dict:
    import yaml

    from tactex_ros.core.paths import config_dir
    return yaml.safe_load((config_dir() / "sensors" / "digit.yaml").read_text())


@pytest.mark.parametrize("change,field", [
    ({"led_intensity": 16}, "led_intensity"),
    ({"serial_lookup": "pyudev"}, "serial_lookup"),
    ({"capture": {"width": 320, "height": 240, "fps": 45}}, "capture"),
    ({"modes": [{"width": 320, "height": 240}]}, "modes.0.fps"),
    ({"colour": "red"}, "colour"),
    ({"crop_fraction": 0.6}, "crop_fraction"),
])
def test_profile_errors_name_the_field(change: dict, field: str) -> None:
    with pytest.raises(InputError, match=field.replace("[", r"\[").replace("]", r"\]")):
        parse_sensor({**_digit_data(), **change})


def test_node_parameters_over_the_profile() -> None:
    c = sensor_config(GelsightSettings(sensor="digit"))
    assert (c.device, c.capture_width, c.capture_height, c.fps, c.crop_fraction,
            c.led_intensity) == ("DIGIT", 320, 240, 60.0, 0.0, 15)
    c = sensor_config(GelsightSettings(sensor="digit", device="/dev/video4",
                                       capture_width=640, capture_height=480, fps=15.0,
                                       led_intensity=3))
    assert (c.device, c.capture_width, c.fps, c.led_intensity) == ("/dev/video4", 640, 15.0, 3)
    with pytest.raises(InputError, match="640x480 at 60 fps is not a mode of sensor 'digit'"):
        sensor_config(GelsightSettings(sensor="digit", capture_width=640, capture_height=480))
    # a recording plays at any rate
    assert sensor_config(GelsightSettings(sensor="digit", fps=50.0), camera=False).fps == 50.0
    with pytest.raises(InputError, match="sensor profile 'nope'.*not found"):
        sensor_config(GelsightSettings(sensor="nope"))
    with pytest.raises(InputError, match="give both or neither"):
        sensor_config(GelsightSettings(capture_width=0))


def test_digit_camera_setup() -> None:
    cap = RecordingCapture()
    got = camera_setup(cap, sensor_config(GelsightSettings(sensor="digit")), revision=200)
    assert cap.props[cv2.CAP_PROP_FRAME_WIDTH] == 320
    assert cap.props[cv2.CAP_PROP_FRAME_HEIGHT] == 240
    assert cap.props[cv2.CAP_PROP_FPS] == 60
    assert cap.props[cv2.CAP_PROP_ZOOM] == (15 << 8) | (15 << 4) | 15
    assert cv2.CAP_PROP_AUTO_EXPOSURE not in cap.props and cv2.CAP_PROP_AUTO_WB not in cap.props
    assert got["led_intensity"] == 4095
    # the GelSight Mini: no frame rate or LED property is set
    cap = RecordingCapture()
    camera_setup(cap, sensor_config(GelsightSettings()))
    assert cv2.CAP_PROP_FPS not in cap.props and cv2.CAP_PROP_ZOOM not in cap.props
    with pytest.raises(InputError, match="led_intensity"):
        camera_setup(RecordingCapture(refuse={cv2.CAP_PROP_ZOOM}),
                     sensor_config(GelsightSettings(sensor="digit")))
    with pytest.raises(InputError, match="firmware revision 101"):
        camera_setup(RecordingCapture(), sensor_config(GelsightSettings(sensor="digit")),
                     revision=101)


def test_led_encoding() -> None:
    assert digit_led_value(0, None) == 0
    assert digit_led_value(1, 200) == 0x111
    with pytest.raises(InputError, match="0..15"):
        digit_led_value(16, None)


def _standin_digit_interface(monkeypatch, digits: list[dict]) -> None:
    mod = types.ModuleType("digit_interface")

    class DigitHandler:
        @staticmethod
        def find_digit(serial):
            return next((d for d in digits if d["serial"] == serial), None)

    mod.DigitHandler = DigitHandler
    monkeypatch.setitem(sys.modules, "digit_interface", mod)


def test_serial_lookup_through_digit_interface(monkeypatch) -> None:
    _standin_digit_interface(monkeypatch, [{"dev_name": "/dev/video7", "serial": "D20001",
                                            "revision": "200", "model": "DIGIT",
                                            "manufacturer": "GelSight"}])
    dev = resolve_device("D20001", "digit_interface")
    assert (dev.path, dev.kind, dev.revision, dev.recording) == ("/dev/video7", "camera", 200,
                                                                 False)
    with pytest.raises(DeviceError, match="lists no DIGIT with that serial"):
        resolve_device("D99999", "digit_interface")
    # not asked for other sensors
    with pytest.raises(DeviceError) as exc:
        resolve_device("D20001", "")
    assert "digit-interface" not in str(exc.value)


def test_serial_lookup_without_digit_interface(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "digit_interface", None)     # import fails
    with pytest.raises(DeviceError, match="digit-interface is not installed"):
        resolve_device("D20001", "digit_interface")


def _frame(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 255, (240, 320, 3), dtype=np.uint8)


def test_frame_folder_order_and_portrait_frames(tmp_path: Path) -> None:
    frames = [_frame(i) for i in range(12)]
    for i, f in enumerate(frames):
        # as digit-interface's get_frame() returns them: transposed and flipped (240 x 320)
        portrait = cv2.flip(cv2.transpose(f), 0)
        assert portrait.shape == (320, 240, 3)
        cv2.imwrite(str(tmp_path / f"frame_{i}.png"), portrait)
    dev = resolve_device(str(tmp_path))
    assert dev.kind == "folder" and dev.recording
    ff, digit = FrameFolder(str(tmp_path)), load_sensor("digit")
    got = []
    while True:
        ok, bgr = ff.read()
        if not ok:
            break
        got.append(landscape(bgr, digit))
    assert len(got) == 12                              # frame_10 after frame_9
    assert all(np.array_equal(a, b) for a, b in zip(got, frames, strict=True))
    assert ff.set(cv2.CAP_PROP_POS_FRAMES, 0) and ff.read()[0]
    # the GelSight profile leaves frames as recorded
    assert landscape(got[0][:200], load_sensor("gelsight_mini")).shape == (200, 320, 3)


def test_frame_folder_refusals(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="without frames"):
        FrameFolder(str(tmp_path))
    (tmp_path / "a.png").write_bytes(b"not an image")
    with pytest.raises(InputError, match="not readable as images"):
        FrameFolder(str(tmp_path))
