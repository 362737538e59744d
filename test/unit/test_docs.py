"""The documentation's links point at files that exist, and every figure under docs/ is listed
in docs/research/figures.md with the command that regenerates it."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
# pages other branches of the same change write (issue 19: docs/hardware_checks.md); tolerated
# only while absent from the tree
PENDING: set[str] = set()    # pages linked before they are written (none today)


def test_relative_links_resolve() -> None:
    broken = []
    for page in PAGES:
        for target in LINK.findall(page.read_text()):
            if "://" in target or target.startswith("mailto:"):
                continue
            path = (page.parent / target).resolve()
            rel = path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else str(path)
            if not path.exists() and rel not in PENDING:
                broken.append(f"{page.relative_to(ROOT)} -> {target}")
    assert broken == []


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_anchors_name_headings() -> None:
    heads = {p.resolve(): {_slug(h) for h in re.findall(r"^#+ (.*)$", p.read_text(), re.M)}
             for p in PAGES}
    broken = []
    for page in PAGES:
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", page.read_text()):
            path = (page.parent / target).resolve() if target else page.resolve()
            if path in heads and anchor not in heads[path]:
                broken.append(f"{page.relative_to(ROOT)} -> {target}#{anchor}")
    assert broken == []


def test_every_figure_is_listed_with_a_command() -> None:
    index = (ROOT / "docs" / "research" / "figures.md").read_text()
    blocks = index.split("\n## ")
    missing = []
    for png in sorted((ROOT / "docs").rglob("*.png")):
        rel = png.relative_to(ROOT).as_posix()
        folder = png.parent.relative_to(ROOT).as_posix() + "/"
        block = next((b for b in blocks if f"`{rel}`" in b.split("\n")[0]
                      or (f"`{folder}`" in b.split("\n")[0] and f"`{png.name}`" in b)), None)
        if block is None or "tactex " not in block:
            missing.append(rel)
    assert missing == []


def test_the_readme_is_a_manual() -> None:
    """At most ~200 lines, the robot's hardware page linked in its first screen."""
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 200
    assert any("docs/hardware.md" in line for line in lines[:40])


CHANGELOG_LIMIT = 25_000     # bytes: a changelog, not a lab notebook (issue 50)
RELEASE = re.compile(r"\[(Unreleased|\d+\.\d+\.\d+)\](?: - (\d{4}-\d{2}-\d{2}))?")
KINDS = ("Added", "Changed", "Deprecated", "Removed", "Fixed", "Security")   # Keep a Changelog


def _version(v: str) -> tuple[int, ...]:
    return tuple(int(x) for x in v.split("."))


def test_the_changelog_is_a_changelog() -> None:
    """CHANGELOG.md in the form of Keep a Changelog: under 25 kB; ``## [Unreleased]`` on top,
    then ``## [X.Y.Z] - YYYY-MM-DD`` newest first, the first of them the package's version;
    every release with its Added, Changed and Fixed; every change one line."""
    text = (ROOT / "CHANGELOG.md").read_text()
    assert len(text.encode()) < CHANGELOG_LIMIT
    sections = re.split(r"^## ", text, flags=re.M)[1:]
    heads = [s.split("\n", 1)[0] for s in sections]
    releases = [RELEASE.fullmatch(h) for h in heads]
    assert all(releases), [h for h, m in zip(heads, releases, strict=True) if not m]
    assert releases[0].group(1) == "Unreleased" and releases[0].group(2) is None
    versions = [(m.group(1), m.group(2)) for m in releases[1:]]
    assert versions and all(date for _, date in versions)
    package = re.search(r"<version>(.*)</version>", (ROOT / "package.xml").read_text()).group(1)
    assert versions[0][0] == package
    assert [_version(v) for v, _ in versions] == sorted((_version(v) for v, _ in versions),
                                                       reverse=True)
    assert len({v for v, _ in versions}) == len(versions)
    assert [d for _, d in versions] == sorted((d for _, d in versions), reverse=True)
    problems = []
    for head, body in zip(heads, sections, strict=True):
        kinds = re.findall(r"^### (.*)$", body, re.M)
        if any(k not in KINDS for k in kinds) or len(set(kinds)) != len(kinds):
            problems.append(f"{head}: subsections {kinds}")
        if not head.startswith("[Unreleased]") and not {"Added", "Changed", "Fixed"} <= set(kinds):
            problems.append(f"{head}: no Added / Changed / Fixed in {kinds}")
        for part in re.split(r"^### .*$", body, flags=re.M)[1:]:
            lines = [line for line in part.splitlines() if line.strip()]
            if not lines or any(not line.startswith("- ") for line in lines):
                problems.append(f"{head}: a change that is not one line: {lines[:3]}")
    assert problems == []


def _sections(page: Path) -> list[tuple[str, list[str]]]:
    """(heading, non-blank lines under it) of a page's ``#`` and ``##`` headings, fenced code
    skipped (its ``# comment`` lines are no headings)."""
    out: list[tuple[str, list[str]]] = []
    fenced = False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        if not fenced and re.match(r"^#{1,2} ", line):
            out.append((line, []))
        elif line.strip() and out:
            out[-1][1].append(line)
    return out


def test_every_research_page_begins_with_a_summary() -> None:
    """Each page under docs/research/ opens, right under its title, with a ``## Summary`` of
    what was measured, the outcome and how its figures are made (at most 30 lines), before
    anything else."""
    pages = sorted((ROOT / "docs" / "research").glob("*.md"))
    assert pages
    bad = []
    for page in pages:
        sections = _sections(page)
        title = sections[0] if sections else ("", [])
        ok = (len(sections) > 1 and title[0].startswith("# ") and title[1] == []
              and sections[1][0] == "## Summary" and 1 <= len(sections[1][1]) <= 30)
        if not ok:
            bad.append(page.name)
    assert bad == []
