"""The operator side of a study session over ROS (``trial.session_run.Operator``), for the
explorer node.

Before each trial of a session the operator is told what to place where, on the latched
prompt topic (``prompt_topic``, ``std_msgs/String``), and confirms the placement through
``~/confirm`` (``std_srvs/srv/Trigger``: recorded as by ``service``) or ``~/confirm_by``
(``tactex/srv/Confirm``: how and by whom, e.g. ``enter`` or ``yes_flag``); ``auto_confirm``
confirms at once. In simulation the mock camera's ``placement`` parameter is set through its
SetParameters service (``placement_service``). The confirmation is published on the prompt
topic too, so every place that shows the prompt shows it.

The running trial is held through ``~/pause``, ``~/resume``, ``~/abort``, ``~/skip`` and
``~/redo`` (``std_srvs/srv/Trigger``: recorded as by ``service``) or ``~/<action>_by``
(``tactex/srv/Confirm``: how and by whom, e.g. ``key`` from the terminal); the requests go to
``trial.control.OperatorControl`` and are recorded through ``record(event)``.
"""

from __future__ import annotations

import threading
import time
from typing import Any
from collections.abc import Callable

from ...core.errors import TrialError
from ...trial import session as sess
from .. import adapter
from ..settings import PROGRESS_TOPIC, ExplorerSettings


class SessionOperator:
    """The operator of the session run by ``node`` (its services, publisher and client are
    made on ``node``, so they go with its configuration). ``stopping()``: True once the node
    is being stopped (a wait ends with TrialError). ``awaiting``: the trial whose placement
    is awaited now (None: none)."""

    def __init__(self, node: Any, settings: ExplorerSettings,
                 stopping: Callable[[], bool],
                 record: Callable[[dict], None] | None = None) -> None:
        from rcl_interfaces.srv import SetParameters
        from std_msgs.msg import String
        from std_srvs.srv import Trigger
        from tactex.srv import Confirm
        self.node, self.settings, self.stopping = node, settings, stopping
        self.awaiting: str | None = None
        self._confirmed = threading.Event()
        self._confirmed_by: tuple[str, str] = ("", "")
        node.create_service(Trigger, "~/confirm", lambda req, res: self._on_confirm(res))
        node.create_service(Confirm, "~/confirm_by",
                            lambda req, res: self._on_confirm(res, req.by or "service",
                                                              req.caller))
        from ...trial.control import ACTIONS, OperatorControl
        self.control = OperatorControl(record or (lambda event: None))
        for action in ACTIONS:
            node.create_service(Trigger, f"~/{action}",
                                lambda req, res, a=action: self._on_action(res, a, "service"))
            node.create_service(Confirm, f"~/{action}_by",
                                lambda req, res, a=action: self._on_action(
                                    res, a, req.by or "service", req.caller))
        self.prompt_pub = node.create_publisher(String, settings.prompt_topic,
                                                adapter.latched_qos())
        self.progress_pub = node.create_publisher(String, PROGRESS_TOPIC,
                                                  adapter.latched_qos())
        self.placement_client = (node.create_client(SetParameters, settings.placement_service)
                                 if settings.placement_service else None)

    def _on_confirm(self, res: Any, by: str = "service", caller: str = "") -> Any:
        """A confirmation (service call): the operator has placed the fabrics of the trial
        being prompted; refused when no placement is awaited."""
        if self.awaiting is None or self._confirmed.is_set():
            res.success, res.message = False, "nothing to confirm: no placement is awaited now"
            return res
        res.success, res.message = True, f"trial {self.awaiting}: placement confirmed"
        self._confirmed_by = (by, caller)
        self._confirmed.set()
        return res

    def _on_action(self, res: Any, action: str, by: str, caller: str = "") -> Any:
        """An operator action (service call) on the running trial; refused with the reason
        when no trial runs or it would change nothing."""
        res.success, res.message = self.control.request(action, by, caller)
        self.node.get_logger().info(res.message + (f" (by {by}" + (f", {caller}" if caller
                                                                   else "") + ")"
                                                   if res.success else " (refused)"))
        return res

    def expect(self, trial_id: str) -> None:
        """A placement of ``trial_id`` is awaited from now on (a quick confirmation counts)."""
        self._confirmed.clear()
        self._confirmed_by = ("", "")
        self.awaiting = trial_id

    def tell(self, text: str) -> None:
        """The prompt on ``prompt_topic``; with ``auto_confirm``, confirmed at once."""
        from std_msgs.msg import String
        self.prompt_pub.publish(String(data=text))
        if self.settings.auto_confirm:
            self._confirmed_by = ("auto_confirm", "the explorer's auto_confirm parameter")
            self._confirmed.set()

    def wait(self) -> tuple[str, str] | None:
        """Wait for the confirmation up to ``confirm_timeout_s``: (how, by whom), None when
        the deadline passed first; TrialError when the node is being stopped."""
        from std_msgs.msg import String
        deadline = time.monotonic() + self.settings.confirm_timeout_s
        try:
            while not self._confirmed.wait(timeout=0.1):
                if self.stopping():
                    raise TrialError("the explorer is stopping")
                if time.monotonic() > deadline:
                    return None
            trial = self.awaiting
        finally:
            self.awaiting = None
        by, caller = self._confirmed_by
        said = f"trial {trial}: placement confirmed by {by}" + (f" ({caller})" if caller else "")
        self.node.get_logger().info(said)
        self.prompt_pub.publish(String(data=said))
        return by, caller

    def place(self, trial: sess.SessionTrial) -> None:
        """Simulation: set the mock camera's ``placement`` (SetParameters), within
        ``server_timeout_s``; TrialError with the camera's reason when it refuses. Hardware
        (no ``placement_service``): nothing, the operator placed the fabrics."""
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters
        client, s = self.placement_client, self.settings
        if client is None:
            return
        if not client.wait_for_service(timeout_sec=s.server_timeout_s):
            raise TrialError(f"placement service {s.placement_service!r} not available within "
                             f"server_timeout_s ({s.server_timeout_s} s)")
        value = ParameterValue(type=ParameterType.PARAMETER_STRING,
                               string_value=sess.placement_text(trial.placement))
        fut = client.call_async(SetParameters.Request(
            parameters=[Parameter(name="placement", value=value)]))
        deadline = time.monotonic() + s.server_timeout_s
        while not fut.done():
            if time.monotonic() > deadline:
                raise TrialError(f"placement service {s.placement_service!r}: no answer within "
                                 f"server_timeout_s ({s.server_timeout_s} s)")
            if self.stopping():
                raise TrialError("the explorer is stopping")
            time.sleep(0.01)
        r = fut.result().results[0]
        if not r.successful:
            raise TrialError(f"the mock camera refused the placement of trial {trial.id}: "
                             f"{r.reason}")
