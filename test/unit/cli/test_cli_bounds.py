"""Bounds on what a user can type: numbers outside their range are refused with the option and
the range named (exit status 2), before anything runs."""

from __future__ import annotations

import pytest

from tactex_ros.cli.main import MAX_COMPARISONS, build_parser, main


@pytest.mark.parametrize("argv, option", [
    (["trial", "--source", "sim", "--comparisons", "1000"], "--comparisons"),
    (["trial", "--source", "sim", "--comparisons", "1"], "--comparisons"),
    (["trial", "--source", "sim", "--seed", "-1"], "--seed"),
    (["trial", "--source", "sim", "--rounds", "100000"], "--rounds"),
    (["trial", "--source", "sim", "--stop-confidence", "nan"], "--stop-confidence"),
    (["trial", "--source", "sim", "--comparisons", "four"], "--comparisons"),
    (["graph", "run", "--sim", "--timeout", "0"], "--timeout"),
    (["graph", "run", "--sim", "--domain-id", "300"], "--domain-id"),
    (["graph", "run", "--sim", "--rounds", "-3"], "--rounds"),
])
def test_out_of_range_refused(argv: list[str], option: str, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        build_parser(argv[0]).parse_args(argv)
    assert e.value.code == 2
    assert option in capsys.readouterr().err


def test_usual_trial_command_still_parses() -> None:
    a = build_parser("trial").parse_args(["trial", "--source", "replay:DIR", "--comparisons", "4",
                                   "--seed", "7", "--json", "F"])
    assert (a.comparisons, a.seed, a.json) == (4, 7, "F")
    a = build_parser("trial").parse_args(["trial", "--source", "sim",
                                   "--comparisons", str(MAX_COMPARISONS)])
    assert a.comparisons == MAX_COMPARISONS


def test_too_many_classes_refused(capsys) -> None:
    names = ",".join(f"x{i}" for i in range(MAX_COMPARISONS + 1))
    assert main(["trial", "--source", "sim", "--classes", names]) == 2
    assert "--classes" in capsys.readouterr().err
