"""The report's charts: ``line_chart``, an inline SVG line chart (series, a dashed stop line,
shaded bands, notes above points) drawn here, no script, no network."""

from __future__ import annotations

import math

from .page import esc

COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf"]


def line_chart(series: dict[str, list[tuple[float, float]]], *, chart_id: str, x_label: str,
               y_label: str, y_max: float = 1.0, width: int = 640, height: int = 260,
               hline: tuple[float, str] | None = None,
               bands: dict[str, list[tuple[float, float, float]]] | None = None,
               notes: dict[str, list[tuple[float, str]]] | None = None) -> str:
    """An inline SVG line chart: ``series`` name -> [(x, y)], y in [0, y_max]. Each series is
    one ``polyline`` (class ``series``) with dots and a legend entry. ``hline``: (y, label) a
    dashed horizontal line (class ``stop-line``); ``bands``: name -> [(x, low, high)] a shaded
    band (class ``band``) behind that series; ``notes``: name -> [(x, text)] small labels above
    the series' points (e.g. n)."""
    ml, mr, mt, mb = 48, 170, 12, 38
    pw, ph = width - ml - mr, height - mt - mb
    xs = [x for pts in series.values() for x, _ in pts] or [0.0, 1.0]
    x0, x1 = min(xs), max(xs)
    if x1 == x0:
        x1 = x0 + 1.0

    def px(x: float) -> float:
        return ml + (x - x0) / (x1 - x0) * pw

    def py(y: float) -> float:
        return mt + ph - max(0.0, min(y, y_max)) / y_max * ph

    out = [f"<svg id='{esc(chart_id)}' xmlns='http://www.w3.org/2000/svg' width='{width}' "
           f"height='{height}' viewBox='0 0 {width} {height}' role='img'>",
           f"<rect x='{ml}' y='{mt}' width='{pw}' height='{ph}' fill='#fafafa' "
           "stroke='#999'/>"]
    for k in range(5):
        y = y_max * k / 4
        out.append(f"<line x1='{ml}' x2='{ml + pw}' y1='{py(y):.1f}' y2='{py(y):.1f}' "
                   f"stroke='#e2e2e2'/><text x='{ml - 6}' y='{py(y) + 4:.1f}' "
                   f"text-anchor='end'>{y:.2g}</text>")
    span = x1 - x0
    step = 10 ** math.floor(math.log10(span / 2)) if span > 2 else 1.0
    while span / step > 10:
        step *= 2
    t = math.ceil(x0 / step) * step
    while t <= x1 + 1e-9:
        out.append(f"<text x='{px(t):.1f}' y='{mt + ph + 16}' text-anchor='middle'>"
                   f"{t:g}</text>")
        t += step
    out.append(f"<text x='{ml + pw / 2}' y='{height - 4}' text-anchor='middle'>"
               f"{esc(x_label)}</text><text x='12' y='{mt + ph / 2}' text-anchor='middle' "
               f"transform='rotate(-90 12 {mt + ph / 2})'>{esc(y_label)}</text>")
    names = list(series)
    for name, band in (bands or {}).items():
        if not band:
            continue
        c = COLOURS[names.index(name) % len(COLOURS)] if name in names else "#999"
        up = " ".join(f"{px(x):.1f},{py(hi):.1f}" for x, _, hi in band)
        down = " ".join(f"{px(x):.1f},{py(lo):.1f}" for x, lo, _ in reversed(band))
        out.append(f"<polygon class='band' data-name='{esc(name)}' points='{up} {down}' "
                   f"fill='{c}' fill-opacity='0.15' stroke='none'/>")
    if hline is not None:
        y, label = hline
        out.append(f"<line class='stop-line' x1='{ml}' x2='{ml + pw}' y1='{py(y):.1f}' "
                   f"y2='{py(y):.1f}' stroke='#b3261e' stroke-dasharray='6 4' "
                   f"stroke-width='1.5'/><text x='{ml + pw - 4}' y='{py(y) - 4:.1f}' "
                   f"text-anchor='end' fill='#b3261e'>{esc(label)}</text>")
    for i, (name, pts) in enumerate(series.items()):
        c = COLOURS[i % len(COLOURS)]
        coords = " ".join(f"{px(x):.1f},{py(y):.1f}" for x, y in pts)
        out.append(f"<polyline class='series' data-name='{esc(name)}' fill='none' "
                   f"stroke='{c}' stroke-width='2' points='{coords}'/>")
        out += [f"<circle cx='{px(x):.1f}' cy='{py(y):.1f}' r='2.5' fill='{c}'/>"
                for x, y in pts]
        out += [f"<text class='note' x='{px(x):.1f}' y='{py(y) - 6:.1f}' "
                f"text-anchor='middle' fill='#555'>{esc(text)}</text>"
                for x, text in (notes or {}).get(name, [])]
        ly = mt + 14 + 16 * i
        out.append(f"<line x1='{ml + pw + 10}' x2='{ml + pw + 28}' y1='{ly - 4}' "
                   f"y2='{ly - 4}' stroke='{c}' stroke-width='3'/><text x='{ml + pw + 32}' "
                   f"y='{ly}' class='legend'>{esc(name)}</text>")
    out.append("</svg>")
    return "".join(out)

