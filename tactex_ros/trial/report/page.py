"""What every report page shares: the page skeleton and its CSS (``page.html``, a
``string.Template`` shipped as package data beside this module), HTML escaping, tables, number,
date and duration formats, inlined PNGs and the atomic write."""

from __future__ import annotations

import base64
import datetime as _dt
import html
from functools import cache
from importlib import resources
from pathlib import Path
from string import Template
from typing import Any

REPORT = "report.html"          # the report's file name in a record or session folder
TEMPLATE = "page.html"          # the page skeleton and CSS ($title, $extra_css, $body)


@cache
def _template() -> Template:
    """The page skeleton, read once from the package (a checkout, a symlinked colcon install
    or a wheel all ship it beside this module)."""
    text = resources.files(__package__).joinpath(TEMPLATE).read_text(encoding="utf-8")
    return Template(text.removesuffix("\n"))


def esc(x: Any) -> str:
    """``x`` as HTML text ('' for None)."""
    return html.escape("" if x is None else str(x))


def png_data(path: Path) -> str | None:
    """A PNG file as a data URI, None when absent."""
    if not path.is_file():
        return None
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode()


def page(title: str, body: str, extra_css: str = "") -> str:
    """A whole HTML page: ``body`` (HTML) under ``title`` (text), the report CSS and
    ``extra_css`` (the page's own rules)."""
    return _template().substitute(title=esc(title), extra_css=extra_css, body=body)


def write_page(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` whole or not at all (WriteError); returns ``path``."""
    from ...core.outputs import write_bytes
    return write_bytes(path, text.encode("utf-8"))


def table(head: list[str], rows: list[list[Any]], left: int = 1, cls: str = "",
          tid: str = "") -> str:
    """An HTML table: ``head`` (text, escaped; [] for none), ``rows`` of cells (HTML);
    the first ``left`` columns left-aligned; ``cls`` its class, ``tid`` its id."""
    th = "".join(f"<th class='{'l' if i < left else ''}'>{esc(h)}</th>"
                 for i, h in enumerate(head))
    th = f"<tr>{th}</tr>" if head else ""
    body = "".join("<tr>" + "".join(f"<td class='{'l' if i < left else ''}'>{c}</td>"
                                     for i, c in enumerate(r)) + "</tr>" for r in rows)
    ident = f" id='{tid}'" if tid else ""
    return f"<table class='{cls}'{ident}>{th}{body}</table>"


def fmt(x: Any, spec: str = ".2f") -> str:
    """``x`` formatted with ``spec`` ('' for None)."""
    return "" if x is None else format(x, spec)


def when(t: float | None) -> str:
    """Epoch seconds as ``YYYY-MM-DD HH:MM:SS UTC``."""
    if not t:
        return ""
    return _dt.datetime.fromtimestamp(t, _dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def duration(s: float | None) -> str:
    """Seconds as ``12.3 s`` (under 2 min) or ``[H h ]M min S s``."""
    if s is None:
        return ""
    s = float(s)
    if s < 120:
        return f"{s:.1f} s"
    h, rest = divmod(int(round(s)), 3600)
    return (f"{h} h " if h else "") + f"{rest // 60} min {rest % 60} s"
