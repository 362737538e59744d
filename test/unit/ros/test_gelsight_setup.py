"""GelSight camera set-up without the camera: the V4L2 properties requested through OpenCV
(capture mode, auto exposure and white balance off), refusals named, numeric device order.
The capture object is a recording stand-in for ``cv2.VideoCapture`` (no sensor here)."""

from __future__ import annotations

import cv2
import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.ros.settings import GelsightSettings
from tactex_ros.ros.nodes.gelsight_node import (V4L2_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL,
                                            _video_number, camera_setup)
from tactex_ros.robot.sensors import sensor_config


def cfg(**kw):
    """The GelSight Mini profile with these node parameters."""
    return sensor_config(GelsightSettings(**kw))


class RecordingCapture:
    """Keeps what was set; refuses the properties in ``refuse``; ``mode`` overrides the size."""

    def __init__(self, refuse=(), mode=None) -> None:
        self.props: dict[int, float] = {}
        self.refuse, self.mode = set(refuse), mode

    def set(self, prop: int, value: float) -> bool:
        if prop in self.refuse:
            return False
        self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        if self.mode and prop == cv2.CAP_PROP_FRAME_WIDTH:
            return self.mode[0]
        if self.mode and prop == cv2.CAP_PROP_FRAME_HEIGHT:
            return self.mode[1]
        return self.props.get(prop, -1.0)


def test_defaults_fix_mode_exposure_and_white_balance() -> None:
    cap = RecordingCapture()
    got = camera_setup(cap, cfg(device="x"))
    assert cap.props[cv2.CAP_PROP_FRAME_WIDTH] == 320
    assert cap.props[cv2.CAP_PROP_FRAME_HEIGHT] == 240
    assert cap.props[cv2.CAP_PROP_AUTO_EXPOSURE] == V4L2_EXPOSURE_MANUAL
    assert cap.props[cv2.CAP_PROP_AUTO_WB] == 0.0
    assert cv2.CAP_PROP_EXPOSURE not in cap.props       # keep the camera's value
    assert got["capture_width"] == 320


def test_values_and_auto_modes() -> None:
    cap = RecordingCapture()
    camera_setup(cap, cfg(device="x", exposure=150.0, white_balance=4500.0))
    assert cap.props[cv2.CAP_PROP_EXPOSURE] == 150.0
    assert cap.props[cv2.CAP_PROP_WB_TEMPERATURE] == 4500.0
    cap = RecordingCapture()
    camera_setup(cap, cfg(device="x", auto_exposure=True, auto_white_balance=True,
                                       exposure=150.0))
    assert cap.props[cv2.CAP_PROP_AUTO_EXPOSURE] == V4L2_EXPOSURE_AUTO
    assert cv2.CAP_PROP_EXPOSURE not in cap.props


def test_refusals_name_the_parameter() -> None:
    with pytest.raises(InputError, match="auto_exposure"):
        camera_setup(RecordingCapture(refuse={cv2.CAP_PROP_AUTO_EXPOSURE}),
                     cfg(device="x"))
    with pytest.raises(InputError, match="capture_width x capture_height = 320x240.*640x480"):
        camera_setup(RecordingCapture(mode=(640, 480)), cfg(device="x"))


def test_devices_in_numeric_order() -> None:
    names = ["/sys/class/video4linux/video10/name", "/sys/class/video4linux/video9/name",
             "/sys/class/video4linux/video2/name"]
    assert [n.split("/")[-2] for n in sorted(names, key=_video_number)] == \
        ["video2", "video9", "video10"]
