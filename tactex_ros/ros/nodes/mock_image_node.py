"""mock_image_node: stands in for the GelSight Mini on the same topic and capture service.

Knows what lies on each platform from the scene (``sim_fabric`` for the simulator,
``replay_class`` for recorded presses). While the mock arm presses a platform (force > 0 and
the sensor within the platform's radius) it publishes that fabric's texture at a gel depth
proportional to the contact force (``depth_per_n``), rendered anew every frame (so the frames
of one press follow the held force); otherwise a no-contact frame. Each press shows a new random
patch of the fabric (new window; a new recorded press for replay sources, whose in-contact
frames, the strongest and ``Touch.extra``, it shows in turn while the press lasts). The capture
service answers from the ring of these frames (``capture.py``): a burst of in-contact frames.

``placement`` (``platform=fabric,...``) puts other catalogue fabrics on platforms over the
scene's ``sim_fabric``; it may be set while the node runs (``ros2 param set``, or the explorer's
study session before each trial through the standard SetParameters service). A new placement
restarts the press numbering, so a session's trial sees the same rendered presses as the same
trial run alone with the same seed. An unknown fabric or platform is refused with the reason.
Preparing a new placement takes seconds (each fabric's height tile): it runs in a helper thread
while the frames go on (their own thread, ``TactexNode.rate_loop``) and the parameter callback keeps
/diagnostics going; the camera's status is meanwhile in the named state "placement change"
(WARN, ERROR only past ``diag_pause_s``).
"""

from __future__ import annotations

import contextlib
import threading

import numpy as np
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from .. import adapter
from ...robot.frames import FrameRing
from ...robot.mock_world import PressCounter
from ...core.errors import InputError
from ..settings import MockImageSettings
from ...robot.scene import load_scene
from .capture import serve_capture
from ..preflight import Stopped
from .lifecycle import TactexNode
from .process import run


class MockImageNode(TactexNode):
    settings_cls = MockImageSettings

    def __init__(self, **kw) -> None:
        super().__init__("mock_image", **kw)

    def configure(self) -> None:
        s = self.settings
        self.scene = load_scene(s.scene_file)
        kind = s.source.partition(":")[0]
        if kind not in ("sim", "replay"):
            raise InputError(f"source {s.source!r}: use sim[:difficulty] or replay:DIR")
        if kind == "sim" and s.source.endswith(":recorded"):
            raise InputError(f"source {s.source!r}: the mock camera is live (one session); "
                              "'recorded' is for offline trials: use sim[:difficulty]")
        from ...sources import open_source
        self.src = open_source(s.source)         # first: a bad source is named as such
        field = "sim_fabric" if kind == "sim" else "replay_class"
        missing = [p.id for p in self.scene.platforms if not getattr(p, field)]
        if missing:
            raise InputError(f"scene {s.scene_file!r}: platforms {missing} have no {field} "
                              f"for source {s.source!r}")
        if kind == "sim":
            self.fabrics = [p.sim_fabric for p in self.scene.ordered]
            for p in self.scene.ordered:
                try:
                    self.src.fabric(p.sim_fabric)
                except InputError as exc:
                    raise InputError(f"scene {s.scene_file!r}: platform {p.id} sim_fabric: "
                                     f"{exc}") from None
            if s.placement:
                self.fabrics = self._placed(s.placement)
            self._prepare(self.fabrics)
            self.add_on_set_parameters_callback(self._on_parameters)
            self._rng = np.random.default_rng([s.seed, 1])
            self.no_contact = self.src.renderer.no_contact(self._rng)
        else:
            from ...sources.replay import read_video
            classes = [p.replay_class for p in self.scene.ordered]
            self.replay = self.src.trial(classes, s.seed)
            first = self.src.presses(classes[0])[0]
            self.no_contact = np.ascontiguousarray(read_video(first)[0][:, :, ::-1]) \
                if first.suffix.lower() in {".mov", ".mp4", ".avi", ".mkv"} else \
                np.full((240, 320, 3), 120, np.uint8)
        self.kind = kind
        self.ring = FrameRing(max(2, int(s.buffer_s * s.fps)))
        self._last_stamp = float("-inf")   # [s] the newest frame's stamp
        self.ring.set_reference(self.no_contact)
        self.lock = threading.Lock()      # the ring, the placement and the press count
        self.position = None
        self.force = 0.0
        self.presses = PressCounter()
        self._press_frames: list[np.ndarray] = []
        self._press_tick = 0
        self._blank = False
        self.pub = self.create_lifecycle_publisher(Image, s.image_topic, qos_profile_sensor_data)
        # the arm's state, read at the frame rate (each frame takes the newest pose and wrench)
        from ..latest import LatestReader
        self.state = LatestReader(self.context, f"{self.get_name()}_state")
        self.pose_in = self.state.subscribe(PoseStamped, s.pose_topic, qos_profile_sensor_data)
        self.wrench_in = self.state.subscribe(WrenchStamped, s.wrench_topic,
                                              qos_profile_sensor_data)
        serve_capture(self, self.ring, self.lock, s.frame_id, s.capture_service)
        from ..diagnostics import CameraHealth, Diagnostics
        self.health = CameraHealth(s.fps, s, simulated=True)
        self.diag = Diagnostics(self, s.diag_period_s)
        self.diag.add("camera", f"mock camera ({s.source})", self.health.check)

    def _placed(self, text: str) -> list[str]:
        """Fabric per platform (scene order) for a ``placement`` text (InputError: why not)."""
        from ...trial.session import parse_placement
        ids = [p.id for p in self.scene.ordered]
        given = parse_placement(text, ids)
        out = [given.get(pid, p.sim_fabric) for pid, p in zip(ids, self.scene.ordered, strict=True)]
        for f in out:
            self.src.fabric(f)               # names an unknown fabric
        return out

    def _prepare(self, fabrics: list[str]) -> None:
        """Build each fabric's height tile now: doing it at the first press stalls the frame
        timer for a moment and the capture window then holds no contact frame."""
        for f in dict.fromkeys(fabrics):
            if not self.context.ok():   # a stop (SIGINT, SIGTERM) ends the building: a tile
                raise Stopped()         # takes seconds on a loaded machine
            self.src.press(f, np.random.default_rng(0))

    def _on_parameters(self, params) -> SetParametersResult:
        """A new ``placement`` while running: checked, prepared, then used from the next frame
        on (press numbering restarts); anything else refused here is refused with the reason."""
        for p in params:
            if p.name != "placement":
                continue
            try:
                fabrics = self._placed(str(p.value))
                self._prepare_live(fabrics)
            except InputError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            with self.lock:
                self.fabrics = fabrics
                self.presses = PressCounter()
            self.get_logger().info("placement: " + ", ".join(
                f"{q.id}={f}" for q, f in zip(self.scene.ordered, fabrics, strict=True)))
        return SetParametersResult(successful=True)

    def _prepare_live(self, fabrics: list[str]) -> None:
        """``_prepare`` in a helper thread while this thread (the executor's, blocked in the
        parameter callback) keeps /diagnostics going (the frames go on in their own thread);
        the camera's status says "placement change" meanwhile (``diag_pause_s``)."""
        import time
        s = self.settings
        failed: list[BaseException] = []

        def work() -> None:
            try:
                self._prepare(fabrics)
            except BaseException as exc:  # noqa: BLE001 - handed to the callback's thread
                failed.append(exc)
        self.health.phase.begin("placement change: preparing the fabrics' tiles",
                                s.diag_pause_s)
        worker = threading.Thread(target=work, name="placement", daemon=True)
        worker.start()
        self.diag.publish()          # the state change goes out now, not at the next period
        next_diag = time.monotonic() + s.diag_period_s
        try:
            while worker.is_alive():
                worker.join(1.0 / s.fps)
                if time.monotonic() >= next_diag:
                    next_diag += s.diag_period_s
                    self.diag.publish()
        finally:
            self.health.phase.end()
            self.diag.publish()
        if failed:
            raise failed[0]

    def activate(self) -> None:
        self.rate_loop(1.0 / self.settings.fps, self._tick, "frames")

    def cleanup(self) -> None:
        state, self.state = getattr(self, "state", None), None
        if state is not None:
            state.close()

    def _read_state(self) -> None:
        """The newest pose and wrench since the last frame (none new: the last ones hold)."""
        pose, wrench = self.pose_in.take(), self.wrench_in.take()
        if pose is not None:
            with contextlib.suppress(InputError):
                self.position = adapter.pose_to_array(pose)[0]
        if wrench is not None:
            self.force = abs(float(wrench.wrench.force.z))   # either wrench sign convention

    def _frame(self) -> np.ndarray:
        self._read_state()
        idx, contact, began = self.presses.update(self.scene.ordered, self.position,
                                                  self.force)
        if began:      # a new press: its faults drawn once
            self._blank = self._rng_fault().random() < self.settings.fault_blank
            if self.kind == "replay":
                t = self.replay(idx)
                self._press_frames = [t.frame] + ([] if t.extra is None else list(t.extra))
                self._press_tick = 0
        if not contact or self._blank:
            return self.no_contact
        if self.kind == "replay":
            self._press_tick += 1
            return self._press_frames[(self._press_tick - 1) % len(self._press_frames)]
        fabric = self.fabrics[idx]
        depth_mm = float(np.clip(self.settings.depth_per_n * self.force, 0.02, 1.0))
        rng = np.random.default_rng([self.settings.seed, self.presses.presses])
        return self.src.press(fabric, rng, depth_mm=depth_mm)

    def _rng_fault(self) -> np.random.Generator:
        return np.random.default_rng([self.settings.seed, self.presses.presses, 99])

    def _tick(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        if now <= self._last_stamp:       # simulated time stood still (a starved /clock):
            return                        # no new instant, so no new frame (one per stamp)
        self._last_stamp = now
        with self.lock:                   # a new placement is swapped in between two frames
            frame = self._frame()
            self.ring.push(now, frame)
        self.health.observe(frame)
        self.pub.publish(adapter.array_to_image(frame, now, self.settings.frame_id))


def main(args: list[str] | None = None) -> int:
    return run(MockImageNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
