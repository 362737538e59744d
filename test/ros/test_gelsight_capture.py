"""The GelSight node's real capture path (OpenCV decode, crop, resize, ring buffer, capture
service) on a real octopi-dev press recording played as the camera."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from tactex_ros import adapter
from tactex_ros.core.contact import contact_score, blur, crop_border
from tactex_ros.graph import NodeSpec
from tactex_ros.runner import Graph

pytestmark = pytest.mark.ros


def _video(octopi_dir: Path) -> Path:
    for cls in sorted(octopi_dir.iterdir()):
        vids = sorted(cls.glob("*.mov"))
        if vids:
            return vids[0]
    pytest.skip("no .mov press in octopi-dev")


def test_capture_returns_strongest_contact_frame(octopi_dir: Path, tmp_path: Path,
                                                 listener) -> None:
    from rclpy.action import ActionClient  # noqa: F401  (rclpy import check)
    from tactex.srv import Capture
    video = _video(octopi_dir)
    # offline: the same pipeline over every frame of the recording
    cap = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        frames.append(crop_border(bgr, 0.15)[:, :, ::-1])
    cap.release()
    n_ref = 3
    ref = np.mean([f.astype(np.float32) for f in frames[:n_ref]], axis=0).round()
    ref_b = blur(ref.astype(np.uint8))
    scores = np.array([contact_score(f, ref_b) for f in frames])

    images = listener.collect(Image, "/tactex/gelsight/image_raw", qos_profile_sensor_data)
    node = NodeSpec("gelsight_node", "gelsight", {
        "device": str(video), "fps": 50.0, "warmup_frames": 0, "reference_frames": n_ref,
        "buffer_s": len(frames) / 50.0, "loop_file": True})
    client = listener.node.create_client(Capture, "/tactex/gelsight/capture")
    with Graph([node], tmp_path / "logs", listener.domain_id):
        assert client.wait_for_service(timeout_sec=30.0)
        end = time.monotonic() + 60.0
        while len(images) < len(frames) and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.5)
        fut = client.call_async(Capture.Request(window_s=0.0))
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.02)
        resp = fut.result()
    assert len(images) >= len(frames)          # the recording plays on a loop
    im0 = images[0]
    assert (im0.height, im0.width, im0.encoding) == (240, 320, "rgb8")
    assert im0.header.frame_id == "gelsight_optical_frame" and im0.header.stamp.sec > 0
    assert resp.success
    got = adapter.image_to_array(resp.image)
    best = int(np.argmax(scores))
    assert np.array_equal(got, frames[best])
    assert resp.contact_score == pytest.approx(scores[best], rel=1e-4)
    assert scores[best] > 3 * np.median(scores[:n_ref] + 1e-3)


def test_unknown_device_refused(tmp_path: Path, listener) -> None:
    node = NodeSpec("gelsight_node", "gelsight", {"device": "No Such Camera 9000"})
    g = Graph([node], tmp_path / "logs", listener.domain_id).start()
    assert g.wait("gelsight", 60.0) == 2
    g.stop()
