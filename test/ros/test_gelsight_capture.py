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

from tactex_ros.ros import adapter
from tactex_ros.core.contact import contact_score, blur, crop_border, in_contact
from tactex_ros.ros.graph import NodeSpec
from tactex_ros.ros.devrun.launcher import Graph

pytestmark = pytest.mark.ros


def _video(octopi_dir: Path) -> Path:
    for cls in sorted(octopi_dir.iterdir()):
        vids = sorted(cls.glob("*.mov"))
        if vids:
            return vids[0]
    pytest.skip("no .mov press in octopi-dev")



def _capture(listener, node, tmp_path: Path, images: list, n_frames: int, settle_s: float):
    """Run ``node`` alone, wait until ``n_frames`` images arrived (60 s deadline), wait
    ``settle_s``, call the capture service once and return its response."""
    from tactex.srv import Capture
    client = listener.node.create_client(Capture, "/tactex/gelsight/capture")
    with Graph([node], tmp_path / "logs", listener.domain_id):
        assert client.wait_for_service(timeout_sec=30.0)
        end = time.monotonic() + 60.0
        while len(images) < n_frames and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(settle_s)
        fut = client.call_async(Capture.Request(window_s=0.0, frames=4))
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.02)
        return fut.result()

def test_capture_returns_strongest_contact_frame(octopi_dir: Path, tmp_path: Path,
                                                 listener) -> None:
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
    resp = _capture(listener, node, tmp_path, images, len(frames), 0.5)
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
    # the burst: frames of the recording next to the strongest, each in contact by the replay
    # source's rule, consecutive at the file's rate (the ring holds the loop from an arbitrary
    # frame on, so a run cut by the loop's seam may give fewer than 3)
    idx = [next(i for i, f in enumerate(frames) if np.array_equal(f, adapter.image_to_array(m)))
           for m in resp.extra_images]
    assert 1 <= len(idx) <= 3 and all(in_contact(scores, best)[i] for i in idx)
    run = sorted((i - best) % len(frames) for i in idx + [best])
    run = sorted(((d + len(frames) // 2) % len(frames)) - len(frames) // 2 for d in run)
    assert run == list(range(run[0], run[0] + len(run))) and 0 in run
    stamps = [adapter.seconds(m.header.stamp) for m in resp.extra_images]
    assert stamps == sorted(stamps)


def test_unknown_device_refused(tmp_path: Path, listener) -> None:
    """No camera by that name: a device absent at run time, exit status 1 (not 2)."""
    node = NodeSpec("gelsight_node", "gelsight", {"device": "No Such Camera 9000"})
    g = Graph([node], tmp_path / "logs", listener.domain_id).start()
    assert g.wait("gelsight", 60.0) == 1
    g.stop()


def _digit_press(folder: Path, n: int = 24, peak: int = 15) -> list[np.ndarray]:
    """A DIGIT press recorded as digit-interface's ``get_frame()`` saves it (portrait PNGs,
    240 wide, 320 high): gel background, then a textured contact that grows and fades.
    Returns the frames in the sensor's landscape orientation, RGB."""
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:240, 0:320].astype(np.float32)
    bg = np.stack([90 + 30 * xx / 320, 120 + 20 * yy / 240, 150 - 25 * xx / 320], axis=-1)
    tex = 25 * np.sin(xx / 3.0) * np.cos(yy / 5.0)
    frames = []
    for i in range(n):
        depth = max(0.0, 1.0 - abs(i - peak) / 6.0) if i >= 3 else 0.0
        f = bg + depth * tex[..., None] + rng.normal(0, 1.5, bg.shape)
        frames.append(np.clip(f, 0, 255).astype(np.uint8))
        portrait = cv2.flip(cv2.transpose(np.ascontiguousarray(frames[-1][:, :, ::-1])), 0)
        cv2.imwrite(str(folder / f"frame_{i}.png"), portrait)
    return frames


def test_digit_profile_on_recorded_frames(tmp_path: Path, listener) -> None:
    """sensor:=digit on a folder of recorded DIGIT frames: the same node and capture service
    return the strongest-contact frame, turned to landscape, 320x240."""
    rec = tmp_path / "digit_press"
    rec.mkdir()
    frames = _digit_press(rec)
    n_ref = 3
    ref_b = blur(np.mean([f.astype(np.float32) for f in frames[:n_ref]], axis=0)
                 .round().astype(np.uint8))
    scores = np.array([contact_score(f, ref_b) for f in frames])
    images = listener.collect(Image, "/tactex/gelsight/image_raw", qos_profile_sensor_data)
    node = NodeSpec("gelsight_node", "gelsight", {
        "sensor": "digit", "device": str(rec), "fps": 30.0, "warmup_frames": 0,
        "reference_frames": n_ref, "buffer_s": len(frames) / 30.0, "loop_file": True})
    resp = _capture(listener, node, tmp_path, images, len(frames), 0.3)
    assert len(images) >= len(frames)
    assert (images[0].height, images[0].width, images[0].encoding) == (240, 320, "rgb8")
    assert resp.success
    best = int(np.argmax(scores))
    assert best == 15
    assert np.array_equal(adapter.image_to_array(resp.image), frames[best])
    assert resp.contact_score == pytest.approx(scores[best], rel=1e-4)
    no_contact = adapter.image_to_array(resp.no_contact)
    assert np.abs(no_contact.astype(int) - frames[0].astype(int)).mean() < 2.0


def test_digit_camera_not_found_refused(tmp_path: Path, listener) -> None:
    """No DIGIT attached: the node ends with exit status 1 (nothing reports 'DIGIT')."""
    node = NodeSpec("gelsight_node", "gelsight", {"sensor": "digit", "device": "D20001"})
    g = Graph([node], tmp_path / "logs", listener.domain_id).start()
    assert g.wait("gelsight", 60.0) == 1
    g.stop()
