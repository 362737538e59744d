"""The one schema system (core/schema.py): presets keep their values, errors are located and name
the field, the explorer's settings are composed from the core's, and ROS parameter descriptors,
command-line options and launch arguments come from the same declarations."""

from __future__ import annotations

import re
from types import SimpleNamespace

import pytest

from tactex_ros.core.config import (PRESETS, SHIPPED_STOP, TRIAL_PRESETS, CnnSettings,
                                    DescriptorSettings, TrialConfig, TrialSettings, preset,
                                    trial_preset)
from tactex_ros.core.schema import field_spec, fields, merge, typed
from tactex_ros.core.errors import InputError
from tactex_ros.ros.settings import ExplorerSettings, MockArmSettings, MotionSettings


def test_presets_keep_their_values() -> None:
    d = preset("default")
    assert d == DescriptorSettings(model="descriptor")
    assert (d.model, d.match_temperature, d.match_prior_scale,
            d.descriptor_frames, d.match_units) == ("descriptor", 0.0251, 1.0, 1, "scene")
    assert d.descriptor_embedding == "sim"
    p = preset("descriptor")            # the 129-number descriptor alone, as before issue 33
    assert (p.descriptor_embedding, p.match_temperature, p.descriptor_height_map) == ("", 0.05,
                                                                                      True)
    assert p.replace(descriptor_embedding="sim", match_temperature=0.0251) == d
    c = preset("cnn")
    assert (c.model, c.input_size, c.epochs, c.steps, c.batch_size, c.lr, c.dropout,
            c.mc_passes, c.bn_recalibrate) == ("small_inception", 48, 0, 8, 32, 3e-3, 0.5, 20, 64)
    s = preset("seed_faithful")
    assert (s.input_size, s.epochs, s.steps, s.lr, s.bn_recalibrate) == (299, 10, 0, 1e-3, 0)
    assert trial_preset("default") == TrialConfig(strategy="infogain", stop_confidence=0.9)
    for name in ("cnn", "seed_faithful"):
        t = trial_preset(name)
        assert (t.strategy, t.stop_confidence, t.rounds, t.touch_retries) == \
            ("variance", 0.0, 20, 2)
    assert set(PRESETS) == set(TRIAL_PRESETS) == {"default", "descriptor", "cnn",
                                                  "seed_faithful"}
    # the class defaults are the shipped method: the default preset adds nothing to them
    assert DescriptorSettings() == preset("default") and TrialConfig() == trial_preset("default")
    assert (TrialConfig().strategy, TrialConfig().stop_confidence) == ("infogain", SHIPPED_STOP)
    # None = an option not given: the preset's value stays
    assert trial_preset("default", strategy=None, rounds=3) == \
        TrialConfig(strategy="infogain", stop_confidence=0.9, rounds=3)


@pytest.mark.parametrize("kw, message", [
    ({"input_size": 8}, "CnnSettings: input_size: Input should be greater than or equal to 32 "
                        "(got 8)"),
    ({"model": "vgg"}, "CnnSettings: model: Input should be 'small_inception', "
                       "'inception_v3' or 'inception_v3_random' (got 'vgg')"),
    ({"epochs": True}, "CnnSettings: epochs: Input should be a valid integer (got True)"),
    ({"lr": "0.1"}, "CnnSettings: lr: Input should be a valid number (got '0.1')"),
    ({"epochs": 2.0}, "CnnSettings: epochs: Input should be a valid integer (got 2.0)"),
    ({"colour": 1}, "CnnSettings: colour: unknown name for a cnn learner; known: model, guards,"),
])
def test_learner_errors_name_the_field(kw: dict, message: str) -> None:
    with pytest.raises(InputError, match="^" + re.escape(message)):
        CnnSettings(**kw)


def test_types_and_assignment() -> None:
    c = CnnSettings(lr=1)                         # an int where a float is expected
    assert c.lr == 1.0 and isinstance(c.lr, float)
    with pytest.raises(ValueError, match="input_size"):
        c.input_size = 4                          # assignments are checked too
    assert c.replace(input_size=64).input_size == 64 and c.input_size == 299
    with pytest.raises(InputError, match="^CnnSettings: input_size: "):
        c.replace(input_size=4)
    with pytest.raises(InputError, match="^configuration 'cnn': dropout: .*0.95"):
        preset("cnn", dropout=0.99)
    with pytest.raises(InputError, match="unknown configuration 'turbo'"):
        preset("turbo")


def test_trial_settings_are_a_preset_plus_overrides() -> None:
    t = TrialSettings.check({"config": "cnn", "trial": {"rounds": 3},
                             "learner": {"threads": 1}})
    assert t.learner == preset("cnn", threads=1)
    assert t.trial == trial_preset("cnn", rounds=3)
    assert TrialSettings().learner == preset("default")
    assert TrialSettings().trial == trial_preset("default")
    with pytest.raises(InputError) as e:
        TrialSettings.check({"config": "cnn", "trial": {"strategy": "greedy", "bogus": 1},
                             "learner": {"input_size": 4}}, "tactex trial")
    msg = str(e.value)
    assert msg.startswith("tactex trial: ")
    assert "learner.input_size: Input should be greater than or equal to 32 (got 4)" in msg
    assert "trial.strategy: Input should be 'variance'" in msg and "(got 'greedy')" in msg
    assert "trial.bogus: unknown name; known: strategy, rounds, stop_confidence" in msg


def test_explorer_settings_are_composed_from_the_core() -> None:
    names = [f.name for f in fields(ExplorerSettings)]
    learner = [f"learner.{n}" for n in CnnSettings.model_fields]
    trial = [f"trial.{n}" for n in TrialConfig.model_fields]
    assert set(learner + trial) <= set(names)
    assert len(names) == len(set(names))
    e = ExplorerSettings(config="cnn", trial={"rounds": 2}, seed=4)
    assert e.learner == preset("cnn") and e.trial.rounds == 2 and e.trial.strategy == "variance"
    spec = field_spec(ExplorerSettings, "trial.rounds")
    assert (spec.kind, spec.default, spec.lo, spec.hi) == (int, 20, 0, 1000)
    spec = field_spec(ExplorerSettings, "config")
    assert spec.read_only and spec.choices == ("default", "descriptor", "seed_faithful", "cnn")
    spec = field_spec(MockArmSettings, "recovery_standin")
    assert (spec.kind, spec.choices) == (str, ("none", "action", "service"))
    assert field_spec(MotionSettings, "stiffness").kind is float


def test_typed_and_merge() -> None:
    assert typed(ExplorerSettings, {"press_timeout_s": 60, "trial": {"rounds": 2}}) == \
        {"press_timeout_s": 60.0, "trial": {"rounds": 2}}
    assert isinstance(typed(ExplorerSettings, {"press_timeout_s": 60})["press_timeout_s"], float)
    with pytest.raises(InputError, match=r"^x: press_timeout_s: .*less than or equal to 3600"):
        typed(ExplorerSettings, {"press_timeout_s": 1e5}, "x")
    assert merge({"a": 1, "t": {"r": 1, "s": "v"}}, None, {"t": {"r": 2}}) == \
        {"a": 1, "t": {"r": 2, "s": "v"}}


def test_ros_descriptors_from_the_schema() -> None:
    pytest.importorskip("rclpy")
    from tactex_ros.ros.nodes.lifecycle import descriptor
    d = descriptor(field_spec(ExplorerSettings, "trial.stop_confidence"))
    assert d.name == "trial.stop_confidence" and not d.read_only
    assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == \
        (0.0, 1.0)
    assert not d.integer_range
    d = descriptor(field_spec(ExplorerSettings, "seed"))
    assert (d.integer_range[0].from_value, d.integer_range[0].to_value) == (0, 2**31 - 1)
    d = descriptor(field_spec(ExplorerSettings, "config"))
    assert d.read_only and d.additional_constraints == \
        "one of: default, descriptor, seed_faithful, cnn"
    d = descriptor(field_spec(ExplorerSettings, "exit_when_done"))
    assert not d.integer_range and not d.floating_point_range


def test_graph_options_parse_text_with_the_schema() -> None:
    from tactex_ros.ros.graph import OPTIONS, option_overrides, parse_option
    assert parse_option("rounds", "5") == 5 and parse_option("exit_when_done", "true") is True
    assert parse_option("strategy", "random") == "random"
    for name, text, what in (("rounds", "abc", "valid integer"), ("rounds", "5000", "1000"),
                             ("strategy", "greedy", "'infogain'"),
                             ("exit_when_done", "maybe", "valid boolean")):
        with pytest.raises(InputError, match=f"^{name}:={text!r}: .*{what}"):
            parse_option(name, text)
    assert option_overrides({"strategy": "random", "rounds": 3, "model": None,
                             "device": "/dev/video2"}) == \
        {"explorer": {"trial": {"strategy": "random", "rounds": 3}},
         "gelsight": {"device": "/dev/video2"}}
    assert set(OPTIONS) >= {"config", "strategy", "model", "rounds", "seed", "device", "source"}


def _launch_module():
    """launch/explore.launch.py imported from its path (it imports launch only where it runs)."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[3] / "launch" / "explore.launch.py"
    spec = importlib.util.spec_from_file_location("tactex_explore_launch", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_launch_arguments_come_from_the_schema(tmp_path) -> None:
    from tactex_ros.ros.graph import OPTIONS
    launch = _launch_module()
    args = {n: (d, h) for n, d, h in launch.arguments()}
    assert set(OPTIONS) <= set(args) and {"sim", "rviz", "robot", "scene"} <= set(args)
    assert args["strategy"][0] == "" and "trial.strategy: exploration strategy" in \
        args["strategy"][1] and "infogain" in args["strategy"][1]
    p = launch.plan({"sim": "true", "rounds": "2", "strategy": "random", "seed": "",
                     "exit_when_done": "true", "record_dir": str(tmp_path)})
    ex = next(n for n in p["nodes"] if n.name == "explorer").parameters
    assert (ex["trial"]["rounds"], ex["trial"]["strategy"]) == (2, "random")
    assert ex["exit_when_done"] is True
    assert ex["seed"] == 0 and ex["record_dir"] == str(tmp_path)     # '' = the node's default
    assert p["sim"] and p["frame"] == "fr3_link0"
    hw = launch.plan({"device": "/dev/video3"})
    assert next(n for n in hw["nodes"] if n.name == "gelsight").parameters == \
        {"device": "/dev/video3"}
    # the robot state the bag records: pose + wrench (FR3 under CRISP), the franka state
    # message (Panda), each in the profile's base frame and default scene
    assert (hw["pose_topic"], hw["wrench_topic"], hw["state_topic"], hw["frame"]) == (
        "/current_pose", "/franka_robot_state_broadcaster/external_wrench_in_base_frame", "",
        "fr3_link0")
    panda = launch.plan({"robot": "panda_crisp"})
    assert (panda["pose_topic"], panda["wrench_topic"], panda["state_topic"],
            panda["frame"]) == ("", "", "/franka_robot_state_broadcaster/robot_state",
                                "panda_link0")
    for values, what in (({"rounds": "abc"}, "launch argument rounds:='abc': "),
                         ({"sim": "maybe"}, "launch argument sim:='maybe': expected true"),
                         ({"sim": "true", "model": "vgg"}, "launch argument model:='vgg': ")):
        with pytest.raises(launch.LaunchArgumentError, match="^" + re.escape(what)):
            launch.plan(values)


def test_launch_argument_trials_reaches_the_explorer_and_is_checked() -> None:
    """trials:=ID,... (part of a session) reaches the explorer; an unknown id is refused
    with the session's ids."""
    from pathlib import Path
    three = str(Path(__file__).parents[2] / "data" / "session_three.yaml")
    launch = _launch_module()
    assert "trials" in {n for n, _, _ in launch.arguments()}
    p = launch.plan({"sim": "true", "session": three, "trials": "2"})
    assert next(n for n in p["nodes"] if n.name == "explorer").parameters["trials"] == "2"
    with pytest.raises(launch.LaunchArgumentError, match=re.escape("(its ids: 1, 2, 3)")):
        launch.plan({"sim": "true", "session": three, "trials": "4"})


def test_launch_resume_settings_file_and_dotted_settings_become_node_parameters(
        tmp_path) -> None:
    """resume:=RECORD, session_dir:=DIR, settings:=FILE and explorer_set:="PATH=VALUE ..."
    reach the explorer as node parameters (the stop threshold set at launch); a bad item is
    refused with the argument and the nearest valid path named."""
    launch = _launch_module()
    rec = tmp_path / "trial_x"
    settings = tmp_path / "explorer.yaml"
    settings.write_text("explorer:\n  ros__parameters:\n    trial: {rounds: 4}\n"
                        "    press_timeout_s: 77.0\n")
    p = launch.plan({"sim": "true", "resume": str(rec), "session_dir": str(tmp_path / "s"),
                     "settings": str(settings),
                     "explorer_set": "trial.stop_confidence=0.95; learner.model=descriptor "
                                     "trial.rounds=5"})
    ex = next(n for n in p["nodes"] if n.name == "explorer").parameters
    assert ex["resume"] == str(rec) and ex["session_dir"] == str(tmp_path / "s")
    assert ex["trial"]["stop_confidence"] == 0.95 and ex["trial"]["rounds"] == 5
    assert ex["press_timeout_s"] == 77.0 and ex["learner"]["model"] == "descriptor"
    # not given: the preset's, resolved before the node starts
    assert launch.plan({"sim": "true"})["nodes"][-1].parameters["trial"][
        "stop_confidence"] == SHIPPED_STOP
    with pytest.raises(launch.LaunchArgumentError,
                       match=re.escape("explorer_set:= 'stop_confidence=0.9'") + ".*"
                       + re.escape("'trial.stop_confidence'")):
        launch.plan({"sim": "true", "explorer_set": "stop_confidence=0.9"})
    with pytest.raises(launch.LaunchArgumentError, match="trial.stop_confidence"):
        launch.plan({"sim": "true", "explorer_set": "trial.stop_confidence=2"})


def test_both_entrances_give_the_explorer_the_same_parameters(tmp_path, capsys) -> None:
    """``ros2 launch`` arguments and ``tactex graph describe`` options for the same run give
    the explorer identical node parameters (resume, session folder, settings file, dotted
    settings)."""
    import json

    from tactex_ros.cli.main import main
    launch = _launch_module()
    settings = tmp_path / "explorer.yaml"
    settings.write_text("press_timeout_s: 70.0\n")
    p = launch.plan({"sim": "true", "rounds": "3", "seed": "2", "settings": str(settings),
                     "session_dir": str(tmp_path / "s"),
                     "explorer_set": "trial.stop_confidence=0.95"})
    assert main(["graph", "describe", "--sim", "--rounds", "3", "--seed", "2",
                 "--settings", str(settings), "--session-dir", str(tmp_path / "s"),
                 "--set", "trial.stop_confidence=0.95"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert [n["parameters"] for n in cli] == [n.parameters for n in p["nodes"]]


def test_launch_help_defaults_exit_status_and_bag_command() -> None:
    """The help of options under the preset shows the preset's values (the run's), not the
    field's own default; a failed node raises (launch then returns 1); rosbag2's topic form
    per distribution."""
    from tactex_ros.ros.graph import option_default
    launch = _launch_module()
    args = {n: h for n, _, h in launch.arguments()}
    assert option_default("strategy") == "infogain" and option_default("model") == "descriptor"
    assert args["strategy"].endswith("('' = the node's default, 'infogain')")
    assert args["model"].endswith("('' = the node's default, 'descriptor')")
    assert launch.node_exited("motion", 0) == "tactex node motion exited"
    for code in (2, 1, -2, None):
        with pytest.raises(launch.NodeFailed):
            launch.node_exited("gelsight", code)
    # the exit handler itself never raises (launch would skip the exit's later handlers):
    # a failure is handed on as its own event, a clean exit shuts the launch down
    failed = []
    handler = launch._on_exit("gelsight", lambda reason: ("shutdown", reason),
                              lambda name, code: failed.append((name, code)) or "emit")
    for code in (2, 1, -2, None):
        assert handler(SimpleNamespace(returncode=code), None) == ["emit"]
    assert failed == [("gelsight", 2), ("gelsight", 1), ("gelsight", -2), ("gelsight", None)]
    assert handler(SimpleNamespace(returncode=0), None) == [
        ("shutdown", launch.node_exited("gelsight", 0))]
    humble = launch.bag_command("/r/bag", ["/a", "/b"], "humble")
    jazzy = launch.bag_command("/r/bag", ["/a", "/b"], "jazzy")
    assert humble == ["ros2", "bag", "record", "-s", "mcap", "-o", "/r/bag", "/a", "/b"]
    assert jazzy == humble[:7] + ["--topics", "/a", "/b"]
    assert launch.bag_command("/r/bag", ["/a"], "kilted")[-2:] == ["--topics", "/a"]


def test_the_schema_names_every_strategy():
    from tactex_ros.core.config import STRATEGY_NAMES
    from tactex_ros.core.strategies import STRATEGIES
    assert set(STRATEGY_NAMES) == set(STRATEGIES)
    from tactex_ros.core.config import REFERENCE_STRATEGIES
    assert set(REFERENCE_STRATEGIES) == {n for n, c in STRATEGIES.items()
                                         if c.includes_reference}


def test_node_params_file_reaches_the_nodes_and_refuses_unknown_ones(tmp_path, capsys) -> None:
    """``--node-params FILE`` (ROS 2 form): each node's values checked by its schema; an
    unknown node or value refused, named."""
    import json

    from tactex_ros.cli.main import main
    f = tmp_path / "nodes.yaml"
    f.write_text("motion: {ros__parameters: {diag_camera_error_s: 1.5}}\n"
                 "mock_image: {ros__parameters: {diag_rate_error: 0.2}}\n")
    assert main(["graph", "describe", "--sim", "--node-params", str(f)]) == 0
    nodes = {n["name"]: n["parameters"] for n in json.loads(capsys.readouterr().out)}
    assert nodes["motion"]["diag_camera_error_s"] == 1.5
    assert nodes["mock_image"]["diag_rate_error"] == 0.2
    for text, named in (("explorer: {ros__parameters: {seed: 1}}\n", "explorer"),
                        ("motion: {ros__parameters: {diag_camera_error_s: -1}}\n",
                         "diag_camera_error_s")):
        f.write_text(text)
        assert main(["graph", "describe", "--sim", "--node-params", str(f)]) == 2
        assert named in capsys.readouterr().err
    assert main(["graph", "describe", "--sim", "--node-params", str(tmp_path / "no")]) == 2
    assert str(tmp_path / "no") in capsys.readouterr().err


def test_the_launch_remembers_what_the_cli_remembers(tmp_path, monkeypatch) -> None:
    """A launch writes the run's options into the record's run.json before any node starts,
    the same options as ``tactex graph run`` (sim, source, seed, the ROS domain, ...); a
    launch with only ``resume:=`` gets them back (the simulated graph and its source)."""
    import json

    from tactex_ros.cli.graph_commands import _nodes
    from tactex_ros.cli.main import build_parser
    from tactex_ros.core.paths import config_dir
    from tactex_ros.ros.run_settings import save_run_file
    from tactex_ros.trial.settings import RUN_FILE
    launch = _launch_module()
    monkeypatch.setenv("ROS_DOMAIN_ID", "7")
    p = launch.plan({"sim": "true", "source": "sim:easy", "seed": "3",
                     "record_dir": str(tmp_path / "l"), "trial_id": "t"})
    d = launch.run_folder(p)
    assert d == tmp_path / "l" / "t"
    by_launch = json.loads((d / RUN_FILE).read_text())
    args = build_parser("graph").parse_args(["graph", "run", "--sim", "--source", "sim:easy",
                                             "--seed", "3", "--domain-id", "7"])
    _nodes(args)
    save_run_file(tmp_path / "c", args.run)
    assert by_launch == json.loads((tmp_path / "c" / RUN_FILE).read_text())
    assert (by_launch["sim"], by_launch["source"], by_launch["domain_id"]) == (True, "sim:easy", 7)

    ex = ExplorerSettings.check({"seed": 3, "scene_file": str(config_dir() / "scene_sim.yaml")})
    (d / "config.json").write_text(json.dumps(ex.record_inputs(3)))
    again = launch.plan({"resume": str(d)})
    assert again["sim"]
    assert next(n for n in again["nodes"] if n.name == "mock_image").parameters["source"] == \
        "sim:easy"
    with pytest.raises(launch.LaunchArgumentError, match="sim:easy"):
        launch.plan({"resume": str(d), "source": "sim:hard"})
    monkeypatch.setenv("ROS_DOMAIN_ID", "8")
    with pytest.raises(launch.LaunchArgumentError, match="domain_id"):
        launch.plan({"resume": str(d)})


def test_a_launch_resume_with_another_threshold_is_refused_before_anything_starts(
        tmp_path) -> None:
    """resume:=RECORD with a stop threshold other than the record's: refused by the launch
    (the setting and both values named), nothing written into the record."""
    import json

    from tactex_ros.core.paths import config_dir
    launch = _launch_module()
    d = tmp_path / "cut"
    d.mkdir()
    ex = ExplorerSettings.check({"scene_file": str(config_dir() / "scene_sim.yaml"),
                                 "trial": {"stop_confidence": 0.6}})
    (d / "config.json").write_text(json.dumps(ex.record_inputs(0)))
    p = launch.plan({"sim": "true", "resume": str(d), "record_dir": str(tmp_path),
                     "explorer_set": "trial.stop_confidence=0.6"})
    assert next(n for n in p["nodes"] if n.name == "explorer").parameters["resume"] == \
        str(d.resolve())
    with pytest.raises(launch.LaunchArgumentError) as err:
        launch.plan({"sim": "true", "resume": str(d),
                     "explorer_set": "trial.stop_confidence=0.7"})
    assert "trial.stop_confidence = 0.7" in str(err.value) and "= 0.6" in str(err.value)
    assert sorted(p.name for p in d.iterdir()) == ["config.json"]
