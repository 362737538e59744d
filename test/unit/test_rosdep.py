"""package.xml's rosdep keys resolve on Humble, Jazzy and Kilted: ``rosdep install --from-paths``
simulated (``scripts/rosdep_keys.py check``) against the committed resolutions of those keys
(``rosdep_keys.yaml``, refreshed from ros/rosdistro by ``scripts/rosdep_keys.py refresh``), and
the pip packages rosdep cannot give are pinned as the venv install pins them."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import yaml
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "rosdep_keys.py"


def _script():
    spec = importlib.util.spec_from_file_location("rosdep_keys", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _check(package_xml: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), "check", "--package-xml",
                           str(package_xml)], capture_output=True, text=True, timeout=60)


def test_every_key_of_package_xml_resolves_on_the_three_distributions():
    r = _check(ROOT / "package.xml")
    assert r.returncode == 0, r.stderr
    doc = yaml.safe_load((ROOT / "rosdep_keys.yaml").read_text())
    assert set(doc["platforms"]) == {"humble", "jazzy", "kilted"}
    assert doc["platforms"]["jazzy"] == ["ubuntu:noble", "debian:bookworm"]
    assert doc["keys"]["python3-rich"]["kilted"]["ubuntu:noble"] == "apt: python3-rich"
    assert doc["keys"]["rclpy"]["humble"]["ubuntu:jammy"] == "apt: ros-humble-rclpy"


def test_the_list_holds_exactly_the_keys_of_package_xml():
    mod = _script()
    doc = yaml.safe_load((ROOT / "rosdep_keys.yaml").read_text())
    assert set(doc["keys"]) == mod.package_keys(ROOT / "package.xml", None)


def test_a_key_without_a_rule_fails_the_resolution(tmp_path: Path):
    text = (ROOT / "package.xml").read_text()
    bad = tmp_path / "package.xml"
    bad.write_text(text.replace("<exec_depend>python3-rich</exec_depend>",
                                "<exec_depend>python3-rich</exec_depend>\n"
                                "  <exec_depend>python3-threadpoolctl</exec_depend>"))
    r = _check(bad)
    assert r.returncode == 1
    assert "python3-threadpoolctl" in r.stderr
    # franka_msgs is released for Humble only: unconditional, it fails Jazzy and Kilted
    bad.write_text(text.replace('<exec_depend condition="$ROS_DISTRO == humble">',
                                "<exec_depend>"))
    r = _check(bad)
    assert r.returncode == 1
    failed = {ln.split(":")[1].split()[0] for ln in r.stderr.splitlines() if "franka_msgs" in ln}
    assert failed == {"jazzy", "kilted"}


def test_rules_follow_rosdeps_precedence():
    rule = _script().rule_for
    assert rule({"ubuntu": ["python3-a"]}, "ubuntu", "noble") == ("apt", ["python3-a"])
    # an installer under the OS, and under an OS version with a wildcard fallback
    assert rule({"debian": {"pip": {"packages": ["g"]}}}, "debian", "bookworm") == ("pip", ["g"])
    versions = {"ubuntu": {"*": {"pip": {"packages": ["g"]}}, "focal": None}}
    assert rule(versions, "ubuntu", "jammy") == ("pip", ["g"])
    assert rule(versions, "ubuntu", "focal") is None
    assert rule({"ubuntu": {"jammy": ["a"]}}, "ubuntu", "noble") is None
    assert rule({"fedora": ["a"]}, "debian", "bookworm") is None
    assert rule({"ubuntu": "a b"}, "ubuntu", "noble") == ("apt", ["a", "b"])


def test_refresh_rebuilds_the_list_from_a_rosdistro_copy(tmp_path: Path):
    src = tmp_path / "rosdistro"
    (src / "rosdep").mkdir(parents=True)
    (src / "rosdep" / "base.yaml").write_text(yaml.safe_dump({"cmake": {"ubuntu": ["cmake"]}}))
    (src / "rosdep" / "python.yaml").write_text(yaml.safe_dump({
        "python3-x": {"ubuntu": {"*": ["python3-x"], "jammy": None}, "debian": ["python3-x"]}}))
    for distro, plats in (("humble", {"ubuntu": ["jammy"]}),
                          ("jazzy", {"ubuntu": ["noble"], "debian": ["bookworm"]}),
                          ("kilted", {"ubuntu": ["noble"], "rhel": ["9"]})):
        (src / distro).mkdir()
        (src / distro / "distribution.yaml").write_text(yaml.safe_dump({
            "release_platforms": plats,
            "repositories": {"ros2": {"release": {"packages": ["rclpy"], "version": "1-1"}}}}))
    pkg = tmp_path / "package.xml"
    pkg.write_text('<?xml version="1.0"?>\n<package format="3"><name>p</name><version>0.1.0'
                   '</version><description>d</description><maintainer email="m@example.com">m'
                   '</maintainer><license>MIT</license><buildtool_depend>cmake'
                   '</buildtool_depend><exec_depend>rclpy</exec_depend><exec_depend>python3-x'
                   '</exec_depend></package>\n')
    out = tmp_path / "keys.yaml"
    assert _script().main(["refresh", str(src), "--out", str(out), "--package-xml", str(pkg),
                           "--commit", "abc"]) == 0
    doc = yaml.safe_load(out.read_text())
    assert doc["rosdistro_commit"] == "abc"
    assert doc["platforms"] == {"humble": ["ubuntu:jammy"],
                                "jazzy": ["ubuntu:noble", "debian:bookworm"],
                                "kilted": ["ubuntu:noble"]}
    assert doc["keys"]["rclpy"]["jazzy"]["debian:bookworm"] == "apt: ros-jazzy-rclpy"
    assert doc["keys"]["python3-x"]["humble"]["ubuntu:jammy"] is None
    assert doc["keys"]["python3-x"]["jazzy"] == {"ubuntu:noble": "apt: python3-x",
                                                 "debian:bookworm": "apt: python3-x"}
    r = subprocess.run([sys.executable, str(SCRIPT), "check", "--package-xml", str(pkg),
                        "--keys", str(out)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "python3-x" in r.stderr


def _pins(path: Path) -> dict[str, str]:
    lines = [ln.split("#")[0].strip() for ln in path.read_text().splitlines()]
    reqs = [Requirement(ln) for ln in lines if ln and not ln.startswith("-")]
    return {r.name.lower(): str(r.specifier) for r in reqs}


def test_the_workspace_pip_file_pins_what_the_venv_pins():
    ros, venv = _pins(ROOT / "requirements-ros.txt"), _pins(ROOT / "requirements.txt")
    assert {"mcap", "taxim", "threadpoolctl", "pydantic"} <= set(ros)
    assert {name: venv.get(name) for name in ros} == ros
    assert not set(ros) & {"torch", "captum", "ray", "matplotlib"}
