"""Two products on disk: the product's pinned requirements (``requirements.txt``) hold, with
what they pull in, every third-party module ``tactex_ros`` imports, and never torch, captum, Ray
or matplotlib; those are the lab's (``requirements-lab.txt``, which includes the product's).
The test tools (pytest, ruff, selenium, ...) are neither's: ``requirements-test.txt`` holds
them, and with the product's every module the unit tests import. Read from the installed
distributions' metadata."""

from __future__ import annotations

import ast
import sys
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[2]
LAB_ONLY = {"torch", "captum", "ray", "matplotlib", "scikit-learn", "joblib"}
TEST_ONLY = {"pytest", "ruff", "mypy", "mypy-baseline", "pytest-xdist", "execnet", "selenium",
             "mcap-ros2-support"}
# the DIGIT sensor's driver, installed by hand (README); ap_gym, the touch environment's
# optional active-perception interface (requirements-test.txt)
OPTIONAL = {"digit_interface", "ap_gym"}


def _pins(path: Path) -> list[Requirement]:
    lines = [ln.split("#")[0].strip() for ln in path.read_text().splitlines()]
    return [Requirement(ln) for ln in lines if ln and not ln.startswith("-r")]


def _closure(reqs: list[Requirement]) -> set[str]:
    """The canonical names of ``reqs`` and every distribution they require, installed here."""
    todo = [(canonicalize_name(r.name), set(r.extras)) for r in reqs]
    seen: set[str] = set()
    while todo:
        name, extras = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        try:
            deps = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            continue
        for d in map(Requirement, deps):
            env = [{"extra": e} for e in extras or {""}]
            if d.marker is None or any(d.marker.evaluate(e) for e in env):
                todo.append((canonicalize_name(d.name), set(d.extras)))
    return seen


def _third_party(folder: Path) -> set[str]:
    tops: set[str] = set()
    for p in folder.rglob("*.py"):
        for n in ast.walk(ast.parse(p.read_text())):
            if isinstance(n, ast.Import):
                tops |= {a.name.split(".")[0] for a in n.names}
            elif isinstance(n, ast.ImportFrom) and n.module and not n.level:
                tops.add(n.module.split(".")[0])
    return {t for t in tops if t not in sys.stdlib_module_names
            and t not in ("tactex", "tactex_ros", "tactex_lab", "test_gelsight_setup")
            and not any((ROOT / "test").rglob(f"{t}.py"))}     # a sibling test module


def test_the_products_requirements_have_no_torch_and_the_lab_includes_them():
    product = _pins(ROOT / "requirements.txt")
    assert not _closure(product) & LAB_ONLY
    lab_text = (ROOT / "requirements-lab.txt").read_text()
    assert "-r requirements.txt" in lab_text.splitlines()
    lab = {canonicalize_name(r.name) for r in _pins(ROOT / "requirements-lab.txt")}
    assert lab >= LAB_ONLY and "torch==2.13.0" in lab_text.splitlines()


def _missing(folders: list[Path], requirements: list[Path]) -> list[str]:
    """Third-party modules imported under ``folders`` that no distribution of
    ``requirements`` (with what they pull in) provides."""
    have = _closure([r for path in requirements for r in _pins(path)])
    owners = metadata.packages_distributions()
    missing = []
    for top in sorted(set().union(*(_third_party(f) for f in folders))):
        dists = {canonicalize_name(d) for d in owners.get(top, [])}
        if top not in OPTIONAL and not dists & have:
            missing.append(f"{top} ({', '.join(sorted(dists)) or 'no distribution'})")
    return missing


def test_every_module_the_product_imports_comes_with_its_requirements():
    assert _missing([ROOT / "tactex_ros"], [ROOT / "requirements.txt"]) == []


def test_every_module_the_unit_tests_import_comes_with_the_test_requirements():
    assert _missing([ROOT / "test" / "unit"],
                    [ROOT / "requirements.txt", ROOT / "requirements-test.txt"]) == []
    # the product's alone do not: selenium is a test tool
    assert "selenium (selenium)" in _missing([ROOT / "test" / "unit"], [ROOT / "requirements.txt"])


def test_the_runtime_requirements_pin_no_test_tool():
    runtime = {canonicalize_name(r.name) for path in ("requirements.txt", "requirements-lab.txt")
               for r in _pins(ROOT / path)}
    test = {canonicalize_name(r.name) for r in _pins(ROOT / "requirements-test.txt")}
    assert not runtime & TEST_ONLY and test >= TEST_ONLY
    assert not test & runtime                    # each pin in one file


def test_package_xml_names_the_products_ros_imports_and_no_lab_dependency():
    import xml.etree.ElementTree as ET
    root = ET.parse(ROOT / "package.xml").getroot()
    deps = {e.text for e in root if e.tag in ("depend", "exec_depend")}
    ros = {t for t in _third_party(ROOT / "tactex_ros")
           if t.endswith(("_msgs", "_srvs", "_interfaces")) or t in ("rclpy",
                                                                      "ament_index_python")}
    assert ros - deps == set() and "rclpy" in ros
    assert not deps & {"python3-torch", "python3-sklearn", "python3-matplotlib",
                       "python3-joblib"}
