"""docs/reference.md is generated from the code: it must equal a fresh generation, and the
generator must find every parameter, argument and option where the code declares them."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from tactex_ros.cli import reference
from tactex_ros.core.schema import Schema, fields, param

ROOT = Path(__file__).resolve().parents[3]
PAGE = ROOT / "docs" / "reference.md"


@pytest.fixture(scope="module")
def fresh() -> str:
    return reference.render()


@pytest.fixture(scope="module")
def lab() -> argparse.ArgumentParser:
    """The lab's parser; skips where the lab's page cannot be generated (a product install:
    no torch)."""
    parser, missing = reference.lab_parser_or_missing()
    if parser is None:
        pytest.skip(missing)
    return parser


def test_the_committed_reference_is_current(fresh: str) -> None:
    """Fails when a parameter, launch argument or option changed without regenerating."""
    old = PAGE.read_text() if PAGE.is_file() else ""
    assert old == fresh, (f"{PAGE.name} is stale: run `make reference` (= "
                          f"`{reference.REGENERATE}` from the repository root) and commit "
                          f"docs/{PAGE.name}")


def test_the_committed_lab_reference_is_current(lab: argparse.ArgumentParser) -> None:
    page = PAGE.parent / reference.LAB_OUT
    old = page.read_text() if page.is_file() else ""
    assert old == reference.render_lab(lab), (f"{page.name} is stale: run `make reference` and "
                                           f"commit docs/{page.name}")


def test_the_product_page_does_not_depend_on_what_is_installed(monkeypatch,
                                                               lab: argparse.ArgumentParser
                                                               ) -> None:
    """No plug-in installed: the product's page is the same; the lab's page still lists the
    lab's commands and learners (read from setup.cfg), none of them on the product's page."""
    from tactex_ros.core import plugins
    with_lab = reference.render()
    monkeypatch.setattr(plugins, "available", lambda group: {})
    assert reference.render() == with_lab
    lab_page = reference.render_lab()
    for name in ("`tactex experiment real`", "`tactex bench latency`", "`tactex sim compare`",
                 "`small_inception`"):
        assert name in lab_page and f"### {name}" not in with_lab, name
    assert "`cnn_auto`" not in lab_page   # the product's ladder over the lab's CNNs, no plug-in
    assert "### `tactex prepare`" in with_lab and "### `tactex prepare`" not in lab_page


def test_every_node_parameter_launch_argument_and_option_is_listed(
        fresh: str, lab: argparse.ArgumentParser) -> None:
    from tactex_ros.ros.graph import SETTINGS
    text = fresh
    for cls in SETTINGS.values():
        for spec in fields(cls):
            assert f"| `{spec.name}` |" in text, spec.name
    launch = reference.launch_arguments()
    for name in ("sim", "rviz", "robot", "scene", "rounds"):
        assert any(line.startswith(f"| `{name}` |") for line in launch), name

    def options(p: argparse.ArgumentParser):
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for sp in a.choices.values():
                    yield from options(sp)
            else:
                yield from a.option_strings
    text += reference.render_lab(lab)
    flags = set(options(lab)) - {"-h", "--help"}
    assert flags and all(f"`{f}`" in text for f in flags), \
        sorted(f for f in flags if f"`{f}`" not in text)


def test_a_new_setting_appears_with_its_type_default_range_and_description() -> None:
    class Probe(Schema):
        speed: float = param(0.5, "how fast [m/s]", 0.1, 2.0)
        mode: str = param("a", "which mode")
    rows = reference.model_rows(Probe)
    assert rows[0] == ("`speed`", "float", "`0.5`", "0.1 .. 2.0", "how fast [m/s]")
    assert rows[1][:3] == ("`mode`", "str", "`a`")


def test_check_mode_reports_a_stale_page(tmp_path, capsys, lab: argparse.ArgumentParser
                                          ) -> None:
    page = tmp_path / "reference.md"
    page.write_text("old\n")
    assert reference.main(["--check", "--out", str(page)]) == 1
    assert page.read_text() == "old\n"
    assert reference.main(["--out", str(page)]) == 0
    assert reference.main(["--check", "--out", str(page)]) == 0


def test_main_builds_the_labs_parser_once(tmp_path, monkeypatch,
                                          lab: argparse.ArgumentParser) -> None:
    built = []
    real = reference.lab_parser
    monkeypatch.setattr(reference, "lab_parser", lambda: built.append(1) or real())
    assert reference.main(["--out", str(tmp_path / "reference.md")]) == 0
    assert len(built) == 1 and (tmp_path / reference.LAB_OUT).is_file()
