"""The capture service shared by the GelSight node and the mock image node.

``tactex/srv/Capture``: the strongest-contact frame of the ring buffer's last ``window_s``
seconds against the no-contact reference frame, with its contact score [grey levels], and a
burst of up to ``frames - 1`` more in-contact frames around it (``FrameRing.burst``:
consecutive frames at the sensor's rate, in time order, each stamped with its capture time).
"""

from __future__ import annotations

import threading

from .. import adapter
from ...robot.frames import FrameRing


def serve_capture(node, ring: FrameRing, lock: threading.Lock, frame_id: str,
                  name: str) -> object:
    """Create the capture service on ``node`` answering from ``ring`` (guarded by ``lock``)."""
    from tactex.srv import Capture

    def handle(req: Capture.Request, resp: Capture.Response) -> Capture.Response:
        now = node.get_clock().now().nanoseconds * 1e-9
        with lock:
            try:
                burst, score = ring.burst(req.window_s, now, max(1, int(req.frames)))
            except ValueError as exc:
                resp.success, resp.reason = False, str(exc)
                return resp
        resp.success, resp.reason = True, ""
        (t0, frame), more = burst[0], burst[1:]
        resp.image = adapter.array_to_image(frame, t0, frame_id)
        resp.extra_images = [adapter.array_to_image(f, t, frame_id) for t, f in more]
        resp.contact_score = score
        if ring.reference is not None:
            resp.no_contact = adapter.array_to_image(ring.reference, now, frame_id)
        return resp

    return node.create_service(Capture, name, handle)
