"""Foxglove layouts for the operator's console, one per robot profile, and their check.

A layout (``configById`` + ``layout`` tree, as Foxglove's Layouts -> Import from file reads it)
shows the graph as the operator needs it during a study: 3D (the explorer's markers and the
profile's end-effector pose), the placement prompt, a button that confirms the placement (the
explorer's ``~/confirm``, ``std_srvs/srv/Trigger``), the belief per comparison platform as a
plot, the latest touch and the live camera image, the contact force and the diagnostics.

The same layout plays a trial's MCAP file (``ros/bag.py``): the markers, the belief
(``/tactex/state``), the touch image and the touches' force (``/tactex/touch_wrench``, a second
line of the force plot beside the live wrench) are in the file; the live topics (the robot's
wrench, the camera, the prompt, the diagnostics) are not recorded there and stay empty.

``PANEL_KEYS`` lists, per panel type, the configuration keys Foxglove reads, from Foxglove's own
config types (github.com/foxglove/studio, packages/studio-base/src/panels/):
``ThreeDeeRender/IRenderer.ts`` ``RendererConfig`` (the 3D and Image panels: ``followTf``,
``followMode``, ...), ``Plot/types.ts`` ``PlotConfig`` (+ ``Plot/internalTypes.ts``
``PlotPath``), ``CallService/types.ts`` ``CallServiceConfig``, ``RawMessages``, the
diagnostics panels' configs, ``Log/types.ts`` ``Config`` (panel type ``RosOut``: the log on
``/rosout``) and ``Indicator/types.ts`` ``IndicatorConfig`` (the explorer's state: its
``explorer: trial`` status level on ``/diagnostics``); every panel's title is ``foxglovePanelTitle`` (``PANEL_TITLE``: the
app keeps a panel's title in its config under that key; the Foxglove SDK's layout model,
``foxglove.layouts`` of the foxglove-sdk package, has no ``title`` in ``PlotConfig``: the
title is the panel's, not the plot's). The CallService buttons set ``editingMode: false``
(only the button shows). ``check_layout`` names every key Foxglove would ignore (e.g. the
old ``followTfFrame``) and every panel that is configured but not placed, or placed but not
configured.

``tactex layout --robot PROFILE`` (or ``write_layouts``) writes ``config/layouts/
tactex_<profile>.foxglove.json``; ``config/tactex.foxglove.json`` is the fr3_crisp one.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from ..robot.robots import load_profile
from .bag import WRENCH_VIEW
from .diagnostics import ERROR, OK, WARN
from .settings import (IMAGE_TOPIC, MARKER_TOPIC, PROMPT_TOPIC, STATE_TOPIC,
                       TOUCH_IMAGE_TOPIC)

#: the explorer's confirm service (``<explorer node>/confirm``; the graph's explorer is
#: ``explorer``)
CONFIRM_SERVICE = "/explorer/confirm"
#: the operator's buttons on the running trial: action -> (text, colour, what it does); each
#: calls ``/explorer/<action>`` (``std_srvs/srv/Trigger``, ``trial/control.py``)
ACTION_BUTTONS = {
    "pause": ("Pause", "#b58900", "no new press until resume (the press under way ends)"),
    "resume": ("Resume", "#17803d", "presses go on"),
    "abort": ("Abort", "#b91c1c", "the session ends after the press under way; resumable"),
    "skip": ("Skip trial", "#6b7280", "the trial ends now, recorded as skipped"),
    "redo": ("Redo trial", "#1d4ed8", "the trial starts again; its presses are kept as "
                                      "superseded"),
}

#: the explorer's trial status on ``/diagnostics`` (``<node>: trial``; the graph's explorer is
#: ``explorer``) and the state indicator's rules: level (0 OK, 1 WARN, 2 ERROR), colour, label
EXPLORER_STATUS = "explorer: trial"
STATE_RULES = ((OK, "#17803d", "explorer OK: exploring or done"),
               (WARN, "#b58900", "explorer WARN: starting, waiting for the operator or paused"),
               (ERROR, "#b91c1c", "explorer ERROR: the trial failed"))

_RENDERER = {"cameraState", "followTf", "followMode", "scene", "publish", "transforms",
             "topics", "layers", "imageMode"}
#: panel type -> configuration keys Foxglove reads (module doc for the sources)
PANEL_KEYS: dict[str, set[str]] = {
    "3D": _RENDERER,
    "Image": _RENDERER,
    "Plot": {"paths", "minYValue", "maxYValue", "minXValue", "maxXValue",
             "showLegend", "legendDisplay", "showPlotValuesInLegend", "showXAxisLabels",
             "showYAxisLabels", "isSynced", "showTooltips", "xAxisVal", "xAxisPath",
             "followingViewWidth", "sidebarDimension"},
    "CallService": {"serviceName", "datatype", "requestPayload", "layout", "buttonText",
                    "buttonTooltip", "buttonColor", "editingMode"},
    "RawMessages": {"topicPath", "diffMethod", "diffTopicPath", "diffEnabled",
                    "showFullMessageForDiff", "expansion", "fontSize"},
    "DiagnosticSummary": {"topicToRender", "minLevel", "pinnedIds", "hardwareIdFilter",
                          "sortByLevel"},
    "DiagnosticStatusPanel": {"topicToRender", "selectedHardwareId", "selectedName",
                              "splitFraction", "numericPrecision", "collapsedSections"},
    "RosOut": {"searchTerms", "minLogLevel", "topicToRender", "nameFilter"},
    "Indicator": {"path", "style", "fallbackColor", "fallbackLabel", "rules"},
}
#: keys of nested objects Foxglove reads (``PlotPath``, ``ImageModeConfig``)
NESTED_KEYS = {("Plot", "paths"): {"value", "enabled", "color", "label", "timestampMethod",
                                   "showLine", "lineSize"},
               ("Indicator", "rules"): {"operator", "rawValue", "color", "label"},
               ("3D", "imageMode"): {"imageTopic", "calibrationTopic", "annotations"},
               ("Image", "imageMode"): {"imageTopic", "calibrationTopic", "annotations"}}
#: the key of a panel's title in its config (every panel type)
PANEL_TITLE = "foxglovePanelTitle"
FOLLOW_MODES = {"follow-pose", "follow-position", "follow-none"}
TOP_KEYS = {"configById", "globalVariables", "userNodes", "linkedGlobalVariables",
            "playbackConfig", "layout"}


def check_layout(layout: dict[str, Any]) -> list[str]:
    """The problems Foxglove would silently ignore in ``layout`` ([] when none)."""
    out = [f"unknown top-level key {k!r}" for k in layout if k not in TOP_KEYS]
    configs = layout.get("configById") or {}
    for pid, cfg in configs.items():
        kind = pid.partition("!")[0]
        keys = PANEL_KEYS.get(kind)
        if keys is None:
            out.append(f"panel {pid!r}: unknown panel type {kind!r} (known: "
                       f"{sorted(PANEL_KEYS)})")
            continue
        out += [f"panel {pid!r}: unknown key {k!r} (Foxglove reads {sorted(keys)})"
                for k in cfg if k not in keys and k != PANEL_TITLE]
        if "followMode" in cfg and cfg["followMode"] not in FOLLOW_MODES:
            out.append(f"panel {pid!r}: followMode {cfg['followMode']!r} (one of "
                       f"{sorted(FOLLOW_MODES)})")
        for (k_kind, key), allowed in NESTED_KEYS.items():
            if k_kind != kind or key not in cfg:
                continue
            items = cfg[key] if isinstance(cfg[key], list) else [cfg[key]]
            for item in items:
                out += [f"panel {pid!r}: {key}: unknown key {k!r}" for k in item
                        if k not in allowed]
    placed = set(re.findall(r'"([A-Za-z0-9 ]+![A-Za-z0-9_-]+)"',
                            json.dumps(layout.get("layout"))))
    out += [f"panel {p!r} is placed but not configured" for p in sorted(placed - set(configs))]
    out += [f"panel {p!r} is configured but not placed" for p in sorted(set(configs) - placed)]
    return out


def foxglove_layout(robot: str = "fr3_crisp", comparisons: tuple[str, ...] =
                    ("c1", "c2", "c3", "c4")) -> dict[str, Any]:
    """The operator's Foxglove layout for robot profile ``robot`` (a name or a path):
    its base frame, pose topic and wrench (``WrenchStamped`` profiles) or full-state force
    (franka state profiles) in the panels; ``comparisons``: the scene's comparison platform
    ids, one belief line each (``/tactex/state.belief[k]``)."""
    prof = load_profile(robot)
    topics: dict[str, Any] = {MARKER_TOPIC: {"visible": True}}
    if prof.pose_topic:
        topics[prof.pose_topic] = {"visible": True}
    if prof.franka_state:       # franka_msgs/FrankaState: O_F_ext_hat_K [Fx Fy Fz ...]
        force = f"{prof.state_topic}.o_f_ext_hat_k[2]"
    else:
        force = f"{prof.wrench_topic}.wrench.force.z"
    configs: dict[str, Any] = {
        "3D!tactex": {"followTf": prof.frame_id, "followMode": "follow-pose",
                      "topics": topics, "layers": {}},
        "RawMessages!prompt": {"topicPath": f"{PROMPT_TOPIC}.data", "diffEnabled": False,
                               "expansion": "all", "fontSize": 16},
        "CallService!confirm": {"serviceName": CONFIRM_SERVICE,
                                "datatype": "std_srvs/srv/Trigger", "requestPayload": "{}",
                                "layout": "horizontal",
                                "buttonText": "Fabrics placed: confirm",
                                "buttonTooltip": "calls the explorer's ~/confirm "
                                                 "(std_srvs/srv/Trigger); recorded as "
                                                 "confirmed by service",
                                "buttonColor": "#17803d", "editingMode": False},
        **{f"CallService!{a}": {"serviceName": CONFIRM_SERVICE.rpartition("/")[0] + "/" + a,
                                "datatype": "std_srvs/srv/Trigger", "requestPayload": "{}",
                                "layout": "horizontal", "buttonText": text,
                                "buttonTooltip": f"calls the explorer's ~/{a} "
                                                 f"(std_srvs/srv/Trigger): {what}; recorded "
                                                 "as by service",
                                "buttonColor": colour, "editingMode": False}
           for a, (text, colour, what) in ACTION_BUTTONS.items()},
        "Plot!belief": {"foxglovePanelTitle": "belief per comparison platform", "paths": [
            {"value": f"{STATE_TOPIC}.belief[{k}]", "enabled": True, "label": pid,
             "timestampMethod": "receiveTime"} for k, pid in enumerate(comparisons)],
            "minYValue": 0, "maxYValue": 1, "showLegend": True, "isSynced": True,
            "xAxisVal": "timestamp"},
        "Image!touch": {"imageMode": {"imageTopic": TOUCH_IMAGE_TOPIC}},
        "Image!live": {"imageMode": {"imageTopic": IMAGE_TOPIC}},
        "RawMessages!state": {"topicPath": STATE_TOPIC, "diffEnabled": False,
                              "expansion": "all"},
        "Plot!wrench": {"foxglovePanelTitle": "contact force [N]", "paths": [
            {"value": force, "enabled": True, "label": "live",
             "timestampMethod": "receiveTime"},
            {"value": f"{WRENCH_VIEW}.wrench.force.z", "enabled": True,
             "label": "touches (recorded)", "timestampMethod": "receiveTime"}],
            "showLegend": True, "isSynced": True, "xAxisVal": "timestamp"},
        "DiagnosticSummary!health": {"topicToRender": "/diagnostics", "minLevel": 0,
                                     "pinnedIds": [], "hardwareIdFilter": ""},
        "DiagnosticStatusPanel!detail": {"topicToRender": "/diagnostics"},
        "RosOut!log": {"topicToRender": "/rosout", "minLogLevel": 2, "searchTerms": []},
        "Indicator!state": {
            "foxglovePanelTitle": "explorer",
            "path": f'/diagnostics.status[:]{{name=="{EXPLORER_STATUS}"}}.level',
            "style": "background", "fallbackColor": "#6b7280",
            "fallbackLabel": "explorer: no status yet",
            "rules": [{"operator": "=", "rawValue": str(level), "color": colour,
                       "label": label} for level, colour, label in STATE_RULES]},
    }
    tree = {
        "direction": "row", "splitPercentage": 50,
        "first": {"direction": "column", "splitPercentage": 30,
                  "first": {"direction": "row", "splitPercentage": 70,
                            "first": {"direction": "column", "splitPercentage": 30,
                                      "first": "Indicator!state",
                                      "second": "RawMessages!prompt"},
                            "second": _column(["CallService!confirm"]
                                              + [f"CallService!{a}" for a in ACTION_BUTTONS])},
                  "second": {"direction": "column", "splitPercentage": 55,
                             "first": "3D!tactex",
                             "second": {"direction": "row", "first": "Image!touch",
                                        "second": "Image!live"}}},
        "second": {"direction": "column", "splitPercentage": 35,
                   "first": "Plot!belief",
                   "second": {"direction": "column", "splitPercentage": 40,
                              "first": {"direction": "row", "first": "RawMessages!state",
                                        "second": "Plot!wrench"},
                              "second": {"direction": "row",
                                         "first": "DiagnosticSummary!health",
                                         "second": {"direction": "column",
                                                    "first": "DiagnosticStatusPanel!detail",
                                                    "second": "RosOut!log"}}}}}
    return {"configById": configs, "globalVariables": {}, "userNodes": {},
            "linkedGlobalVariables": [], "playbackConfig": {"speed": 1}, "layout": tree}


def _column(panels: list[str]) -> Any:
    """A column of ``panels``, equal heights (Foxglove's binary mosaic tree)."""
    if len(panels) == 1:
        return panels[0]
    return {"direction": "column", "splitPercentage": round(100 / len(panels), 1),
            "first": panels[0], "second": _column(panels[1:])}


def layout_text(robot: str = "fr3_crisp") -> str:
    """The layout as the JSON text that is shipped (2-space indent, newline at the end)."""
    return json.dumps(foxglove_layout(robot), indent=2) + "\n"


def write_layouts(config: Path, robots: tuple[str, ...] = ("fr3_crisp", "panda_crisp", "sim")
                  ) -> list[Path]:
    """Write ``config/layouts/tactex_<robot>.foxglove.json`` for each robot profile and
    ``config/tactex.foxglove.json`` (fr3_crisp's); their paths."""
    out = []
    (config / "layouts").mkdir(exist_ok=True)
    for r in robots:
        p = config / "layouts" / f"tactex_{r}.foxglove.json"
        p.write_text(layout_text(r))
        out.append(p)
    (config / "tactex.foxglove.json").write_text(layout_text("fr3_crisp"))
    return out + [config / "tactex.foxglove.json"]
