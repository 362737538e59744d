"""Figure helpers of the experiments (matplotlib, Agg backend, PNG files).

Each helper draws one figure, writes it and returns the path; none keeps global figure state.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np


def _plt():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


def lines(path: Path, x: Sequence[float], series: dict[str, tuple[Sequence, Sequence | None]],
          xlabel: str, ylabel: str, title: str, ylim: tuple[float, float] | None = None,
          hlines: dict[str, float] | None = None) -> Path:
    """One line per series (mean, optional std band) against ``x``."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, (mean, std) in series.items():
        m = np.asarray(mean, dtype=float)
        xx = np.asarray(x, dtype=float)[:m.size]
        line, = ax.plot(xx, m, marker="o", ms=3, label=name)
        if std is not None:
            s = np.asarray(std, dtype=float)
            ax.fill_between(xx, m - s, m + s, color=line.get_color(), alpha=0.15)
    for name, y in (hlines or {}).items():
        ax.axhline(y, ls="--", lw=1, color="grey")
        ax.text(ax.get_xlim()[0], y, f" {name}", va="bottom", fontsize=8, color="grey")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if ylim:
        ax.set_ylim(*ylim)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def bars(path: Path, groups: Sequence[str], series: dict[str, tuple[Sequence, Sequence | None]],
         ylabel: str, title: str, reference: dict[str, Sequence[float | None]] | None = None,
         ylim: tuple[float, float] | None = (0.0, 1.0)) -> Path:
    """Grouped bars: one group per entry of ``groups``, one bar per series (mean, std error bar).

    ``reference``: named marker rows (e.g. the thesis's numbers), one value (or None) per group.
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(5.0, 1.3 * len(groups) + 2), 4.2))
    k = max(1, len(series))
    width = 0.8 / k
    xs = np.arange(len(groups))
    for i, (name, (mean, std)) in enumerate(series.items()):
        ax.bar(xs + (i - (k - 1) / 2) * width, mean, width, yerr=std, capsize=3, label=name)
    markers = "x*^v"
    for j, (name, vals) in enumerate((reference or {}).items()):
        pts = [(x, v) for x, v in zip(xs, vals) if v is not None]
        if pts:
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], marker=markers[j % 4],
                       color="black", zorder=5, label=name)
    ax.set_xticks(xs)
    ax.set_xticklabels(groups, rotation=0 if len(groups) < 7 else 45, ha="center"
                       if len(groups) < 7 else "right")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if ylim:
        ax.set_ylim(*ylim)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def confusion(path: Path, cm: np.ndarray, labels: Sequence[str], title: str,
              normalise: bool = True) -> Path:
    """A confusion matrix (rows = truth); cells show counts, colour the row-normalised share."""
    return confusion_grid(path, {title: cm}, labels, normalise=normalise)


def confusion_grid(path: Path, cms: dict[str, np.ndarray], labels: Sequence[str],
                   normalise: bool = True, suptitle: str | None = None) -> Path:
    """Several confusion matrices side by side (same labels)."""
    plt = _plt()
    n = len(cms)
    side = max(3.2, 0.32 * len(labels) + 1.8)
    fig, axes = plt.subplots(1, n, figsize=(side * n, side + 0.8), squeeze=False)
    small = len(labels) <= 12
    for ax, (title, cm) in zip(axes[0], cms.items()):
        cm = np.asarray(cm, dtype=float)
        rows = cm.sum(axis=1, keepdims=True)
        shown = np.divide(cm, rows, out=np.zeros_like(cm), where=rows > 0) if normalise else cm
        ax.imshow(shown, cmap="Blues", vmin=0, vmax=1 if normalise else None)
        ax.set_xticks(range(len(labels)))
        ax.set_yticks(range(len(labels)))
        fs = 7 if small else 5
        ax.set_xticklabels(labels, rotation=90, fontsize=fs)
        ax.set_yticklabels(labels, fontsize=fs)
        ax.set_xlabel("predicted")
        ax.set_ylabel("true")
        ax.set_title(title, fontsize=9)
        if small:
            for i in range(cm.shape[0]):
                for j in range(cm.shape[1]):
                    if cm[i, j]:
                        ax.text(j, i, f"{int(cm[i, j])}", ha="center", va="center", fontsize=7,
                                color="white" if shown[i, j] > 0.6 else "black")
    if suptitle:
        fig.suptitle(suptitle)
    return _save(fig, path)


def heatmap(path: Path, values: np.ndarray, rows: Sequence[str], cols: Sequence[str],
            title: str, xlabel: str = "", ylabel: str = "", vmin: float = 0.0,
            vmax: float = 1.0, fmt: str = "{:.2f}") -> Path:
    """A table of values (e.g. per-trial accuracy, trials x strategies) as a heat map."""
    plt = _plt()
    values = np.asarray(values, dtype=float)
    fig, ax = plt.subplots(figsize=(1.1 * len(cols) + 2.5, 0.22 * len(rows) + 1.6))
    im = ax.imshow(values, cmap="viridis", vmin=vmin, vmax=vmax, aspect="auto")
    ax.set_xticks(range(len(cols)))
    ax.set_xticklabels(cols, fontsize=8)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(rows, fontsize=6 if len(rows) > 20 else 8)
    if values.size <= 400:
        for i in range(values.shape[0]):
            for j in range(values.shape[1]):
                if np.isfinite(values[i, j]):
                    ax.text(j, i, fmt.format(values[i, j]), ha="center", va="center",
                            fontsize=6, color="white" if values[i, j] < (vmin + vmax) / 2
                            else "black")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    fig.colorbar(im, ax=ax, fraction=0.04)
    return _save(fig, path)
