"""The newest message of a topic, taken when the reader asks (at its own pace) instead of
delivered by the executor at the writer's rate.

Every message an executor delivers costs rclpy's executor a wake (about 0.7 ms of CPU in
``SingleThreadedExecutor``): a node that only ever uses the latest robot state, at a lower
rate than the state is published, pays that 100 or 1000 times a second for nothing. Here the
subscriptions live on a helper node that no executor spins; ``Latest.take`` drains the
reader's history (the DDS reader keeps the last ``depth`` samples) and returns the newest.
The helper node (``<name>``) is in the caller's context: same participant, same domain.
"""

from __future__ import annotations

from typing import Any

from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter


class Latest:
    """One topic's newest message (``take``)."""

    def __init__(self, sub: Any) -> None:
        self._sub = sub

    def take(self) -> Any:
        """The newest message that arrived since the last ``take`` (older ones are dropped),
        or None when none did."""
        newest = None
        sub = self._sub
        with sub.handle:
            while True:
                got = sub.handle.take_message(sub.msg_type, sub.raw)
                if got is None:
                    return newest
                newest = got[0]


class LatestReader:
    """A helper node ``name`` (in ``context``, never spun) holding subscriptions read with
    ``Latest.take``; ``close`` destroys it."""

    def __init__(self, context: Context, name: str) -> None:
        self.node = Node(name, context=context, use_global_arguments=False,
                         start_parameter_services=False, enable_rosout=False,
                         parameter_overrides=[
                             Parameter("start_type_description_service", value=False)])

    def subscribe(self, msg_type: type, topic: str, qos: Any) -> Latest:
        """``topic``'s newest ``msg_type`` message, subscribed with ``qos`` (its publisher's)."""
        return Latest(self.node.create_subscription(msg_type, topic, lambda _m: None, qos))

    def close(self) -> None:
        """Destroy the helper node (once; after the context was shut down its entities went
        with it, and nothing is left to destroy)."""
        node, self.node = self.node, None
        if node is not None and node.context.ok():
            node.destroy_node()
