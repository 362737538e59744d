"""`tactex experiment stop-rules` (first cut) end to end on the simulator: both rules run on the
same scenes; the summary's figures are those of its rows."""

import json

from tactex_ros.cli.main import main


def test_stop_rules_paired_on_the_simulator(tmp_path):
    f = tmp_path / "s.json"
    assert main(["experiment", "stop-rules", "--source", "sim", "--scenes", "2",
                 "--comparisons", "3", "--rounds", "3", "--file", str(f)]) == 0
    out = json.loads(f.read_text())
    for name in ("threshold", "evalue"):
        rows, r = out["rows"][name], out["rules"][name]
        assert len(rows) == 2
        assert r["accuracy"] == sum(x["correct"] for x in rows) / 2
        assert r["sure_and_wrong"] == sum(x["sure"] and not x["correct"] for x in rows) / 2
        assert all(0 <= x["extra"] <= 3 for x in rows)
    assert 0 <= out["mcnemar_p"] <= 1


def test_stop_rules_refuses_a_bad_count(capsys):
    assert main(["experiment", "stop-rules", "--source", "sim", "--scenes", "0",
                 "--file", "x.json"]) == 2
    assert "--scenes" in capsys.readouterr().err
