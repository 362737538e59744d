"""The HTML reports of fixed records, byte for byte against the pages kept in
``test/unit/data/reports/`` (the report package's split changed no page), and what the
session report and the report index say.

``TACTEX_WRITE_GOLDEN=1`` rewrites the kept pages from the code (after a deliberate change of a
page: review the diff)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.paths import config_dir
from tactex_ros.trial import session as sess
from tactex_ros.trial.record import TrialRecord, append_event

GOLDEN = Path(__file__).parent / "data" / "reports"
T0 = 1_764_000_000.0          # [s] epoch of the fixed records (2025-11-24)
PLACEMENT = {"reference": "satin", "c1": "denim", "c2": "satin", "c3": "felt", "c4": "linen"}


def _img(rng: np.random.Generator) -> np.ndarray:
    return rng.integers(0, 255, (6, 8, 3), dtype=np.uint8)     # small: the pages stay small


def _started(root: Path, name: str, session: str | None = None) -> TrialRecord:
    """A record with its inputs (scene, config.json with the run's context) and nothing else;
    ``session``: its session's name (a session trial)."""
    rec = TrialRecord(root, name)
    cfg = {"explorer": {"seed": 5, "config": "default",
                        "scene_file": str(config_dir() / "scene_sim.yaml")},
           "trial": {"strategy": "infogain", "stop_confidence": 0.9, "rounds": 4},
           "learner": {"model": "descriptor"},
           "run": {"started": T0, "version": "9.9.9", "commit": "abc123def456",
                   "host": "lab", "command": "tactex graph run --sim --session s.yaml",
                   "non_default": {"explorer.seed": 5}}}
    if session is not None:
        cfg["session"] = {"name": session, "trial": name.removeprefix("trial_"),
                          "truth": ["c2"], "placement": PLACEMENT}
    rec.save_inputs(config_dir() / "scene_sim.yaml", cfg)
    return rec


def finished_trial(root: Path, name: str = "trial_1", answer: str = "c2",
                   sure: bool = True, session: str | None = None) -> Path:
    """A finished record: five touches (one with a failed attempt), two decisions, the run's
    context; ``session``: its session's name (a session trial)."""
    rec = _started(root, name, session)
    rng = np.random.default_rng(1)
    ids = list(PLACEMENT)
    nc = np.full((6, 8, 3), 90, np.uint8)
    for k, pid in enumerate(ids):
        rec.add_touch(_img(rng), {"platform_id": pid, "platform_index": k, "accepted": True,
                                  "force_n": 4.0 + 0.1 * k, "depth_m": 4e-4,
                                  "attempts": 2 if k == 0 else 1,
                                  "attempt_failures": "attempt 1: capture failed" if k == 0
                                  else None,
                                  "requested": T0 + 10 + 10 * k, "stamp": T0 + 12 + 10 * k},
                      no_contact=nc)
    best = ids.index(answer) - 1
    for r, t in ((1, T0 + 55.0), (2, T0 + 70.0)):
        b = [0.1] * 4
        b[best] = 0.6 if r == 1 else (0.95 if sure else 0.55)
        rec.add_decision({"round": r, "next": "c1" if r == 1 else "", "belief": b,
                          "uncertainty": [0.5, 0.2, 0.2, 0.1], "touches": [r, 1, 1, 1],
                          "decision_s": 1.5, "done": r == 2, "time": t,
                          "prediction": answer if r == 2 else ""})
    rec.finish({"prediction": answer, "touches": 5,
                "stop_reason": "confident" if sure else "rounds", "sure": sure,
                "strategy": "infogain", "model": "descriptor", "elapsed_s": 60.0,
                "truth_platforms": ["c2"], "correct": answer == "c2"})
    return rec.dir


def unfinished_trial(root: Path) -> Path:
    """A record interrupted twice and resumed once, with no result."""
    rec = TrialRecord(root, "t9")
    rec.save_inputs(config_dir() / "scene_sim.yaml",
                    {"trial": {"stop_confidence": 0.9, "rounds": 4},
                     "run": {"command": "tactex graph run --sim --scene x.yaml"}})
    rng = np.random.default_rng(2)
    for k in range(3):
        rec.add_touch(_img(rng), {"platform_id": "c1", "platform_index": 1, "accepted": True,
                                  "requested": T0 + 100 + 10 * k, "stamp": T0 + 102 + 10 * k})
    append_event(rec.dir, {"event": "trial_ended", "reason": "SIGINT", "time": T0 + 125})
    append_event(rec.dir, {"event": "resumed", "after_touch": 3, "touches_replayed": 3,
                           "time": T0 + 500, "how": "re-training"})
    rec.add_touch(_img(rng), {"platform_id": "c2", "platform_index": 2, "accepted": True,
                              "requested": T0 + 510, "stamp": T0 + 512})
    append_event(rec.dir, {"event": "trial_ended", "reason": "node motion ended",
                           "time": T0 + 520})
    return rec.dir


def session_folder(root: Path, n_trials: int = 6) -> Path:
    """A session of ``n_trials`` (at least 4) trials: 1 sure and right, 2 not sure, 3 skipped,
    4 started and interrupted, the rest never started; operator events and an interruption."""
    d = root / "s"
    d.mkdir(parents=True)
    trials = [{"id": str(k), "position": k - 1, "seed": k, "truth": ["c2"],
               "placement": PLACEMENT} for k in range(1, n_trials + 1)]
    (d / sess.SESSION_FILE).write_text(json.dumps({
        "name": "s", "path": "s.yaml", "session_id": "s-1", "trial_file_sha256": "0" * 64,
        "trials": trials, "settings": {"seed": 0, "rounds": 4}}))
    sess.add_event(d, {"event": "started", "time": T0})
    sess.add_event(d, {"event": "trial_started", "trial": "1", "time": T0 + 1})
    finished_trial(d, "trial_1", "c2", True, session="s")
    sess.add_event(d, {"event": "trial_done", "trial": "1", "prediction": "c2",
                       "correct": True, "touches": 5, "time": T0 + 80})
    sess.add_event(d, {"event": "trial_started", "trial": "2", "time": T0 + 81})
    sess.add_event(d, {"event": "operator", "action": "pause", "trial": "2", "by": "key",
                       "caller": "", "time": T0 + 90})
    sess.add_event(d, {"event": "operator", "action": "resume", "trial": "2",
                       "by": "service", "caller": "foxglove", "time": T0 + 95})
    finished_trial(d, "trial_2", "c1", False, session="s")
    sess.add_event(d, {"event": "trial_done", "trial": "2", "prediction": "c1",
                       "correct": False, "sure": False, "touches": 5, "time": T0 + 160})
    sess.add_event(d, {"event": "trial_started", "trial": "3", "time": T0 + 161})
    sess.add_event(d, {"event": "operator", "action": "skip", "trial": "3",
                       "by": "service", "caller": "", "time": T0 + 170})
    _started(d, "trial_3", "s").finish({"skipped": True, "touches": 0})
    sess.add_event(d, {"event": "trial_done", "trial": "3", "skipped": True,
                       "touches": 0, "time": T0 + 171})
    sess.add_event(d, {"event": "trial_started", "trial": "4", "time": T0 + 172})
    _started(d, "trial_4", "s")
    sess.add_event(d, {"event": "run_ended", "reason": "SIGINT", "time": T0 + 900})
    from tactex_ros.trial.report import write_trial_report
    for k in (1, 2, 3):                 # as a session writes them: each trial that ended
        write_trial_report(d / f"trial_{k}")
    return d


def _pages(root: Path) -> dict[str, str]:
    """The pages of the fixed records, their folder written as ``ROOT``."""
    from tactex_ros.trial.report import session_html, trial_html
    out = {"trial": trial_html(finished_trial(root / "a")),
           "unfinished": trial_html(unfinished_trial(root / "b"))}
    sd = session_folder(root / "c")
    out["session"] = session_html(sd)
    out["session_trial"] = trial_html(sd / "trial_2")
    return {k: v.replace(str(root.resolve()), "ROOT").replace(str(root), "ROOT")
            for k, v in out.items()}


def test_the_pages_of_fixed_records_are_the_kept_ones(tmp_path: Path) -> None:
    pages = _pages(tmp_path)
    if os.environ.get("TACTEX_WRITE_GOLDEN"):
        GOLDEN.mkdir(parents=True, exist_ok=True)
        for k, v in pages.items():
            (GOLDEN / f"{k}.html").write_text(v)
    for k, v in pages.items():
        kept = (GOLDEN / f"{k}.html").read_text()
        assert v == kept, f"{k}.html differs from {GOLDEN / k}.html"
    assert len(pages["trial"]) > 10_000


def test_the_pages_do_not_depend_on_where_the_records_lie(tmp_path: Path) -> None:
    assert _pages(tmp_path / "x") == _pages(tmp_path / "y")


def _cells(page: str, table_id: str) -> dict[str, str]:
    """First cell -> second cell (tags dropped) of each row of the table ``table_id``."""
    import html
    import re
    t = page[page.index(f"id='{table_id}'"):]
    t = t[:t.index("</table>")]
    rows = [re.findall(r"<td[^>]*>(.*?)</td>", r) for r in t.split("<tr>")[1:]]
    return {html.unescape(re.sub("<[^>]+>", "", r[0])): html.unescape(re.sub("<[^>]+>", "",
                                                                            r[1]))
            for r in rows if len(r) >= 2}


def test_the_session_report_gives_the_trials_context_and_links_only_to_reports(
        tmp_path: Path) -> None:
    import re

    from tactex_ros.trial.report import regenerate, session_html
    d = session_folder(tmp_path, n_trials=32)
    page = session_html(d)
    ctx = _cells(page, "context")
    assert ctx["tactex"] == "9.9.9 · commit abc123def456"
    assert ctx["command"] == "tactex graph run --sim --session s.yaml"
    assert ctx["stop threshold"] == "belief ≥ 0.9" and ctx["rounds cap"] == "4"
    assert "trial.rounds=4" in ctx["settings changed from the preset"]
    assert ctx["model"] == "descriptor" and ctx["simulation or robot"].startswith("simulation")
    # a link only where the trial's report is: 1, 2 (answered) and 3 (skipped); 4 started
    # without a report, 5..32 never started: listed, no link (was: 29 dead links)
    links = re.findall(r"<a href='(trial_\d+)/report.html'", page)
    assert links == ["trial_1", "trial_2", "trial_3"]
    assert all((d / x / "report.html").is_file() for x in links)
    rows = re.findall(r"<tr><td class='l'>(?:<a [^>]*>)?(\d+)<", page[page.index("<h2>Trials"):])
    assert rows == [str(k) for k in range(1, 33)]
    assert page.count("not started<") == 28
    regenerate(d)                       # `tactex report`: the started trial 4 gets its report
    assert re.findall(r"<a href='(trial_\d+)/report.html'", session_html(d)) == [
        "trial_1", "trial_2", "trial_3", "trial_4"]
    # each operator action named: when, what, which trial, who
    ops = page[page.index("id='operator-actions'"):]
    ops = ops[:ops.index("</table>")]
    got = [[re.sub("<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", r)]
           for r in ops.split("<tr>")[2:]]
    assert got == [["2025-11-24 16:01:30 UTC", "pause", "2", "key"],
                   ["2025-11-24 16:01:35 UTC", "resume", "2", "service, foxglove"],
                   ["2025-11-24 16:02:50 UTC", "skip", "3", "service"]]
    assert re.search(r"id='operator-count'>3<", page)


def test_the_session_context_says_which_trials_ran_otherwise(tmp_path: Path) -> None:
    from tactex_ros.trial.report import session_html
    d = session_folder(tmp_path)
    cfg_path = d / "trial_2" / "config.json"
    cfg = json.loads(cfg_path.read_text())
    cfg["run"]["commit"] = "fedcba987654"                 # trial 2 resumed on another commit
    cfg["trial"].update(stop_rule="evalue", stop_alpha=0.03)
    cfg_path.write_text(json.dumps(cfg))
    ctx = _cells(session_html(d), "context")
    assert ctx["tactex"] == ("9.9.9 · commit abc123def456 (trials 1, 3, 4)"
                             "9.9.9 · commit fedcba987654 (trial 2)")
    assert ctx["stop threshold"] == "belief ≥ 0.9"          # trials 1, 3 and 4
    assert ctx["stop rule"] == "e-value: P(ever stopping wrong) ≤ alpha = 0.03, null: library (the evidence model's)"
    empty = tmp_path / "e"
    d2 = session_folder(empty)
    for k in (1, 2, 3, 4):
        import shutil
        shutil.rmtree(d2 / f"trial_{k}")
    assert "no trial started" in _cells(session_html(d2), "context")["how it ran"]


def test_a_folder_of_records_gets_an_index_of_them(tmp_path: Path) -> None:
    import re

    from tactex_ros.core.errors import InputError
    from tactex_ros.trial.report import regenerate
    root = tmp_path / "lab"
    finished_trial(root / "2025" / "week1", "t_sure", "c2", True)
    finished_trial(root / "2025" / "week1", "t_unsure", "c1", False)
    unfinished_trial(root / "2025" / "week2")
    session_folder(root / "study")
    bad = root / "old" / "broken"
    bad.mkdir(parents=True)
    (bad / "config.json").write_text("{}")
    (bad / "touches.jsonl").write_text('{"seq": 1}\nnot json\n{"seq": 3}\n')
    (root / ".hidden" / "t").mkdir(parents=True)
    (root / ".hidden" / "t" / "config.json").write_text("{}")
    out = regenerate(root)
    assert out[-1] == root / "index.html"
    assert {p.name for p in out[:-1]} == {"report.html"}
    page = (root / "index.html").read_text()
    trials = _rows(page, "trials")
    # the lone trials and the session's 4 started (superseded ones left out), newest first
    got = {r[2]: r for r in trials}
    assert set(got) == {"t_sure", "t_unsure", "t9", "trial_1", "trial_2", "trial_3",
                        "trial_4"}
    assert got["t_sure"][5:8] == ["correct", "5", "60.0"]
    assert got["t_sure"][4].startswith("c2 (") and got["trial_1"][4] == "c2 (satin)"
    assert got["t_unsure"][5] == "not sure"                       # never "correct"
    assert got["trial_2"][4:6] == ["c1 (denim)", "not sure"]
    assert got["t9"][5:8] == ["unfinished", "4", "34.0"]
    assert got["trial_3"][5] == "skipped" and got["trial_1"][1] == "s"
    assert got["t_sure"][0] == "2025-11-24 16:00:00 UTC" and got["t_sure"][3] == "scene_sim.yaml"
    dates = [r[0] for r in trials if r[0]]
    assert dates == sorted(dates, reverse=True)
    sessions = _rows(page, "sessions")
    assert sessions == [["2025-11-24 16:00:00 UTC", "s", "3 of 6", "0.500 (1 not sure, "
                         "1 skipped)", "1", "15 min 0 s"]]
    # every link opens a report on disk; the damaged record is named, not linked
    links = re.findall(r"href='([^']+)'", page)
    assert len(links) == 1 + 7 and all((root / x).is_file() for x in links)
    assert "week1/t_sure/report.html" in [Path(x).as_posix().removeprefix("2025/")
                                          for x in links]
    damaged = _rows(page, "damaged")
    assert [r[0] for r in damaged] == ["old/broken"] and "touches.jsonl" in damaged[0][1]
    assert ".hidden" not in page
    # a single record still gives its report alone; a folder with none is refused
    assert regenerate(root / "2025" / "week1" / "t_sure") == [
        root / "2025" / "week1" / "t_sure" / "report.html"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError):
        regenerate(tmp_path / "empty")


def _rows(page: str, table_id: str) -> list[list[str]]:
    """The data rows of table ``table_id`` as text cells."""
    import html
    import re
    t = page[page.index(f"id='{table_id}'"):]
    t = t[:t.index("</table>")]
    return [[html.unescape(re.sub("<[^>]+>", "", c)) for c in
             re.findall(r"<td[^>]*>(.*?)</td>", r)] for r in t.split("<tr>")[2:]]


def test_the_page_template_ships_as_package_data() -> None:
    """``page.html`` lies beside the report modules and setup.cfg ships it (a wheel and the
    colcon install carry it); the skeleton takes the title, the page's CSS and the body."""
    import configparser
    from fnmatch import fnmatch

    from tactex_ros.trial.report import page
    here = Path(page.__file__).parent
    assert (here / page.TEMPLATE).is_file()
    cfg = configparser.ConfigParser()
    cfg.read(Path(__file__).parents[2] / "setup.cfg")
    pats = [x.strip() for x in cfg["options.package_data"]["tactex_ros.trial.report"].split(",")]
    assert any(fnmatch(page.TEMPLATE, x) for x in pats)
    html = page.page("a <b>", "<p id='x'>$body</p>", ".x{color:red}")
    assert html.startswith("<!DOCTYPE html>") and html.endswith("</body></html>")
    assert "<title>a &lt;b&gt;</title>" in html and ".x{color:red}</style>" in html
    assert "<p id='x'>$body</p>" in html          # a $ in the body is the body's own text


def test_session_and_not_sure_trial_reports_in_a_real_browser(tmp_path: Path) -> None:
    """Headless Chromium on a session's reports: the session's context table and operator
    actions, the not-sure trial's verdict and both of its belief charts drawn, the accuracy
    chart; screenshots kept in test-artifacts/."""
    import shutil
    wd = pytest.importorskip("selenium.webdriver")
    chrome, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not chrome or not driver:
        pytest.skip("headless chromium + chromedriver not installed")
    from selenium.webdriver.chrome.service import Service

    from tactex_ros.trial.report import regenerate
    d = session_folder(tmp_path)
    regenerate(d)
    opts = wd.ChromeOptions()
    opts.binary_location = chrome
    for a in ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
              "--disable-background-networking", "--disable-component-update",
              "--disable-sync", "--window-size=1200,2400",
              f"--user-data-dir={tmp_path / 'chrome-profile'}"):
        opts.add_argument(a)
    drv = wd.Chrome(service=Service(driver), options=opts)
    art = Path(__file__).parents[2] / "test-artifacts"
    art.mkdir(exist_ok=True)

    def width(chart: str) -> float:
        return drv.execute_script(f"return document.getElementById('{chart}').getBBox().width")
    try:
        drv.get((d / "report.html").as_uri())
        ctx = drv.find_element("id", "context")
        assert ctx.is_displayed()
        for text in ("abc123def456", "belief ≥ 0.9", "rounds cap", "trial.rounds=4",
                     "tactex graph run --sim --session s.yaml"):
            assert text in ctx.text, text
        assert len(drv.find_elements("css selector", "#operator-actions .operator")) == 3
        assert drv.find_elements("css selector", "#accuracy-chart polyline.series")
        assert width("accuracy-chart") > 300
        drv.save_screenshot(str(art / "session_report.png"))
        drv.find_element("css selector", "a[href='trial_2/report.html']").click()
        # not sure, and its best guess is not the true match
        assert drv.find_element("id", "not-sure").text == "not sure"
        assert drv.find_element("id", "not-sure").is_displayed()
        assert drv.find_element("id", "verdict").text == "wrong"
        assert "abc123def456" in drv.find_element("id", "context").text
        for chart in ("belief-chart", "belief-time-chart"):
            lines = drv.find_elements("css selector", f"#{chart} polyline.series")
            assert len(lines) == 4 and all(x.get_attribute("points") for x in lines)
            assert width(chart) > 300
        drv.save_screenshot(str(art / "trial_report_not_sure.png"))
    finally:
        drv.quit()
