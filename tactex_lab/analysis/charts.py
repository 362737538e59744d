"""Every figure of the package (matplotlib, Agg backend, PNG files): experiments and reports.

Each helper draws one figure, writes it and returns the path; none keeps global figure state.
"""

from __future__ import annotations

from pathlib import Path
import math
from collections.abc import Sequence

import numpy as np

from tactex_lab.analysis.stats import pareto_front, wilson


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
        pts = [(x, v) for x, v in zip(xs, vals, strict=True) if v is not None]
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
    for ax, (title, cm) in zip(axes[0], cms.items(), strict=True):
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


def pareto(path: Path, rows: dict[str, dict], title: str, mark: str | None = None,
           reference: str = "default", xkey: str = "median_cpu_s") -> Path:
    """Accuracy (Wilson interval) against decision time (log) per setting; the Pareto front,
    ``mark`` (e.g. the thesis's setting) and ``reference`` highlighted."""
    plt = _plt()
    labels = [k for k, v in rows.items() if not math.isnan(v[xkey])]
    pts = [(rows[k][xkey], rows[k]["accuracy"]) for k in labels]
    front = pareto_front(pts)
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for i, k in enumerate(labels):
        t, a = pts[i]
        lo, hi = rows[k]["ci95"]
        color = ("tab:red" if k == mark else "tab:green" if k == reference
                 else "tab:blue" if i in front else "tab:gray")
        ax.errorbar([t], [a], yerr=[[a - lo], [hi - a]], fmt="o", color=color, ms=6,
                    capsize=2, alpha=0.9)
        ax.annotate(k, (t, a), textcoords="offset points", xytext=(5, 4 - 9 * (i % 3)),
                    fontsize=7)
    if front:
        ax.step([pts[i][0] for i in front], [pts[i][1] for i in front], where="post",
                color="tab:blue", lw=1, alpha=0.6, label="Pareto front")
    if mark in labels:
        ax.plot([], [], "o", color="tab:red", label=f"thesis setting ({mark})")
    ax.plot([], [], "o", color="tab:green", label=reference)
    ax.set_xscale("log")
    ax.set_xlabel("decision time per round, median CPU seconds (log scale; 1 torch thread per "
                  "process)")
    ax.set_ylabel("trial accuracy (95 % Wilson interval)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower right")
    return _save(fig, path)


def touch_curves(path: Path, curves: dict[str, dict], title: str) -> Path:
    """Accuracy against total touches, one line per strategy."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for s, c in curves.items():
        ax.plot(c["touches"], c["accuracy"], marker="o", ms=3, label=s)
    ax.set_xlabel("total touches (baseline of 5 included)")
    ax.set_ylabel("trial accuracy")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def faithful(path: Path, summary: dict, title: str, mark: str) -> Path:
    """Accuracy and median decision time of ``mark`` (red) against the other settings."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(8, 3.6))
    labels = list(summary)
    acc = [summary[k]["accuracy_final"] for k in labels]
    a1.bar(labels, acc, color=["tab:red" if k == mark else "tab:green" for k in labels])
    for i, k in enumerate(labels):
        a1.text(i, acc[i] + 0.02, f"{summary[k]['correct']}/{summary[k]['n']}", ha="center")
    a1.set_ylim(0, 1.1)
    a1.set_ylabel("trial accuracy")
    a2.bar(labels, [summary[k]["median_decision_s"] for k in labels],
           color=["tab:red" if k == mark else "tab:green" for k in labels])
    a2.set_yscale("log")
    a2.set_ylabel("median decision time [s]")
    fig.suptitle(title, fontsize=9)
    return _save(fig, path)


def accuracy_axis(path: Path, axis: str, values: list[float], series: dict[str, list[float]],
                  threshold: float, title: str) -> Path:
    """Accuracy of each series along one perturbation axis; failure threshold and chance."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for name, acc in series.items():
        ax.plot(values, acc, marker="o", ms=4, label=name)
    ax.axhline(threshold, color="k", ls="--", lw=0.8, label=f"threshold {threshold:g}")
    ax.axhline(0.25, color="gray", ls=":", lw=0.8, label="chance (4 platforms)")
    ax.set_xlabel(axis)
    ax.set_ylabel("trial accuracy")
    ax.set_ylim(0, 1.05)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)


def failure_modes(path: Path, rows: list[tuple[str, dict]], title: str) -> Path:
    """Stacked share of failed trials by mode per condition (``row["modes"]``: {mode: count},
    the same modes in the same order in every row)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(6, 0.35 * len(rows) + 2), 4.5))
    bottom = np.zeros(len(rows))
    modes = list(rows[0][1]["modes"])
    # the palette may be longer than the modes: zip stops at the last mode
    colors = dict(zip(modes, ["black", "tab:red", "tab:purple", "tab:orange", "tab:brown",
                              "tab:gray"], strict=False))
    for m in modes:
        v = np.array([r["modes"][m] / max(1, r["n"]) for _, r in rows])
        ax.bar(range(len(rows)), v, bottom=bottom, color=colors[m], label=m)
        bottom += v
    ax.set_xticks(range(len(rows)))
    ax.set_xticklabels([k for k, _ in rows], rotation=70, fontsize=7)
    ax.set_ylabel("share of trials that failed, by mode")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)
    return _save(fig, path)


def guards(path: Path, rows: list[dict], title: str) -> Path:
    """Accuracy with guards off and on per (axis, value, strategy)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(rows) + 2), 4))
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r["without"]["accuracy"] for r in rows], 0.4, label="guards off",
           color="tab:gray")
    ax.bar(x + 0.2, [r["with"]["accuracy"] for r in rows], 0.4, label="guards on",
           color="tab:green")
    ax.set_xticks(x)
    ax.set_xticklabels([f"{r['axis']}={r['value']:g}\n{r['strategy']}" for r in rows],
                       fontsize=7)
    ax.set_ylabel("trial accuracy")
    ax.set_ylim(0, 1.05)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return _save(fig, path)


def auto_compute(path: Path, values: list[float], rows: dict[str, list[dict]], title: str
                 ) -> Path:
    """Accuracy and CPU seconds per trial against difficulty, one line per model."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for name, blocks in rows.items():
        a1.plot(values, [b["accuracy"] for b in blocks], marker="o", label=name)
        a2.plot(values, [b["cpu_per_trial_s"] for b in blocks], marker="o", label=name)
    a1.set_xlabel("difficulty q")
    a1.set_ylabel("trial accuracy")
    a1.set_ylim(0, 1.05)
    a2.set_xlabel("difficulty q")
    a2.set_ylabel("CPU seconds per trial (decisions)")
    a2.set_yscale("log")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle(title, fontsize=9)
    return _save(fig, path)


def _bands(ax, series: dict[str, dict]) -> None:
    """One line per series with its 95 % band, the number of scenes in the legend."""
    for lab, v in series.items():
        line, = ax.plot(v["x"], v["accuracy"], marker="o", ms=3, label=f"{lab} (n = {v['n']})")
        ax.fill_between(v["x"], v["lo"], v["hi"], color=line.get_color(), alpha=0.12)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def band_series(correct: np.ndarray, x: Sequence[float]) -> dict:
    """Accuracy with its 95 % Wilson band at each point of ``x``: ``correct`` (n scenes, K)
    bool, scene i right at point k. {"x", "accuracy", "lo", "hi" (lists of K), "n"}."""
    c = np.asarray(correct, dtype=bool)
    if c.ndim != 2 or c.shape[1] != len(x):
        raise ValueError(f"correct must be (scenes, {len(x)}), got {c.shape}")
    n = int(c.shape[0])
    right = c.sum(axis=0)
    bands = [wilson(int(s), n) for s in right]
    return {"x": [float(v) for v in x], "accuracy": [float(s) / n if n else float("nan")
                                                    for s in right],
            "lo": [b[0] for b in bands], "hi": [b[1] for b in bands], "n": n}


def trial_time(touches: Sequence[int], baseline: int, press_s: float, decision_s: float
               ) -> list[float]:
    """Trial time [s] after ``k`` touches after the baseline: (baseline + k) presses of
    ``press_s`` and k + 1 decisions of ``decision_s`` (one after the baseline, one per touch)."""
    return [(baseline + k) * press_s + (k + 1) * decision_s for k in touches]


def accuracy_bands(path: Path, series: dict[str, dict], xlabel: str, title: str) -> Path:
    """Accuracy against touches or time, one line per setting with its 95 % band and its number
    of scenes in the legend. ``series``: {label: ``band_series``} ({"x", "accuracy", "lo",
    "hi", "n"})."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    _bands(ax, series)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("accuracy (95 % Wilson band)")
    ax.set_title(title, fontsize=9)
    low = min([min(v["lo"]) for v in series.values() if v["lo"]] or [0.0])
    ax.set_ylim(max(0.0, np.floor((low - 0.05) * 10) / 10), 1.02)
    return _save(fig, path)


def accuracy_panels(path: Path, panels: dict[str, dict[str, dict]], title: str) -> Path:
    """One ``accuracy_bands`` panel per entry of ``panels`` ({x label: series}), side by
    side: e.g. accuracy against the severity of each perturbation, one line per method."""
    plt = _plt()
    n = max(1, len(panels))
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.8), squeeze=False)
    # no panels: the one axis stays empty
    for ax, (xlabel, series) in zip(axes[0], panels.items(), strict=False):
        _bands(ax, series)
        ax.set_ylim(0.0, 1.02)
        ax.set_xlabel(xlabel, fontsize=8)
    axes[0][0].set_ylabel("accuracy (95 % Wilson band)")
    fig.suptitle(title, fontsize=9)
    return _save(fig, path)


def touches_and_time(out: Path, rows: dict[str, tuple[np.ndarray, float]], baseline: int,
                     press_s: float, title: str, press_note: str = "") -> list[Path]:
    """``out``/accuracy_vs_touches.png and ``out``/accuracy_vs_time.png, one line per setting
    with its Wilson band and scenes. ``rows``: {label: (correct (n scenes, K + 1) bool, right
    after k = 0..K touches after the baseline; the setting's median decision time [s])}; the time
    axis is ``trial_time`` with ``press_s`` seconds per press (``press_note``: where it comes
    from, shown in the axis label)."""
    by_touch, by_time = {}, {}
    for lab, (correct, decision_s) in rows.items():
        ks = list(range(np.asarray(correct).shape[1]))
        by_touch[lab] = band_series(correct, ks)
        by_time[lab] = band_series(correct, trial_time(ks, baseline, press_s, decision_s))
    note = f" ({press_note})" if press_note else ""
    return [accuracy_bands(Path(out) / "accuracy_vs_touches.png", by_touch,
                           "touches after the baseline", title),
            accuracy_bands(Path(out) / "accuracy_vs_time.png", by_time,
                           f"trial time [s]: ({baseline} + k) presses x {press_s:.2f} s{note}"
                           " + decisions", title)]


def stop_sweep(path: Path, rows: list[dict], labels: Sequence[str]) -> Path:
    """Accuracy at the stop against mean touches until the stop, one line per setting over its
    stop thresholds (``rows``: {"setting", "touches", "accuracy"})."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for lab in labels:
        mine = [r for r in rows if r["setting"] == lab]
        ax.plot([r["touches"] for r in mine], [r["accuracy"] for r in mine], marker="o",
                ms=3, label=lab)
    ax.set_xlabel("touches after the baseline until the stop (mean)")
    ax.set_ylabel("accuracy at the stop")
    ax.set_title("stop threshold sweep (report scenes)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def save_small(fig, path: Path, dpi: int = 80) -> Path:
    """Write a figure as a 128-colour palette PNG (maps of textures compress badly); closes it."""
    import io

    from PIL import Image
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    _plt().close(fig)
    buf.seek(0)
    Image.open(buf).convert("RGB").quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(
        path, optimize=True)
    return path


def saliency_panel(ax_row, img: np.ndarray, ixg: np.ndarray, cam: np.ndarray,
                   titles: tuple[str, str, str] = ("input", "Input x Gradient", "Grad-CAM"),
                   label: str | None = None) -> None:
    """Draw one row: input, Input x Gradient (heat map), Grad-CAM overlaid on the input."""
    ax_row[0].imshow(img)
    ax_row[1].imshow(ixg, cmap="inferno", vmin=0, vmax=1)
    ax_row[2].imshow(img)
    ax_row[2].imshow(cam, cmap="jet", alpha=0.45, vmin=0, vmax=1)
    for a, t in zip(ax_row, titles, strict=True):
        a.set_xticks([])
        a.set_yticks([])
        if t:
            a.set_title(t, fontsize=8)
    if label:
        ax_row[0].set_ylabel(label, fontsize=7)


def saliency_rows(path: Path, labels: Sequence[str], imgs, ixg, cam, probs,
                  targets: Sequence[int], title: str) -> Path:
    """One row per image (N, S, S, 3): input, Input x Gradient, Grad-CAM; the row's label with
    the probability of its target (and "wrong" when another class wins)."""
    plt = _plt()
    n = len(labels)
    fig, axes = plt.subplots(n, 3, figsize=(5.4, 1.75 * n + 0.5), squeeze=False)
    for i in range(n):
        pred = int(np.argmax(probs[i]))
        saliency_panel(axes[i], imgs[i], ixg[i], cam[i],
                       titles=("input", "Input x Gradient", "Grad-CAM") if i == 0
                       else ("", "", ""),
                       label=f"{labels[i][:18]}\np={probs[i][targets[i]]:.2f}"
                             f"{'' if pred == targets[i] else ' (wrong)'}")
    fig.suptitle(title, fontsize=8)
    return save_small(fig, path)


def gradcam_rounds(path: Path, labels: Sequence[str], maps: list[tuple], title: str) -> Path:
    """Grad-CAM overlays of one image per class (rows) after up to 7 decisions (columns).

    ``maps``: per decision (round, images (N, S, S, 3), ixg, cam (N, S, S), probs (N, N))."""
    plt = _plt()
    show = [m for i, m in enumerate(maps) if i % max(1, len(maps) // 6) == 0 or
            i == len(maps) - 1][:7]
    fig, axes = plt.subplots(len(labels), len(show) + 1,
                             figsize=(1.45 * (len(show) + 1), 1.5 * len(labels) + 0.5),
                             squeeze=False)
    for i in range(len(labels)):
        axes[i][0].imshow(show[0][1][i])
        axes[i][0].set_ylabel(labels[i][:14], fontsize=6)
        for j, (rnd, imgs, _, cam, probs) in enumerate(show):
            a = axes[i][j + 1]
            a.imshow(imgs[i])
            a.imshow(cam[i], cmap="jet", alpha=0.45, vmin=0, vmax=1)
            a.set_title(f"r{rnd} p={probs[i][i]:.2f}", fontsize=6)
        for a in axes[i]:
            a.set_xticks([])
            a.set_yticks([])
    axes[0][0].set_title("input", fontsize=6)
    fig.suptitle(title, fontsize=8)
    return save_small(fig, path)


def sim_vs_real(path: Path, real: Sequence, sim: Sequence, ranking: dict | None) -> Path:
    """The sim-to-real picture: top row real presses, bottom row simulated (up to 4 each, two
    per press group), each beside |contact - no contact| x8; with ``ranking``
    (``experiments.ranking.run_ranking``) a last column of sim against real accuracy per setting.
    ``real``, ``sim``: ``analysis.sim_vs_real.Press`` items."""
    picks = {"real": [], "sim": []}
    for side, presses in (("real", real), ("sim", sim)):
        for g in ("soft", "firm_textured", "smooth"):
            named = {p.name: p for p in reversed(presses) if p.group == g}  # first per name
            picks[side] += list(named.values())[::-1][:2]
        picks[side] = picks[side][:4]
    k = min(4, len(picks["real"]), len(picks["sim"]))
    ncols = 2 * k + (1 if ranking else 0)
    fig, axes = _plt().subplots(2, ncols, figsize=(2 * ncols, 3.4), squeeze=False)
    for i in range(k):
        for row, side in enumerate(("real", "sim")):
            p = picks[side][i]
            axes[row, 2 * i].imshow(p.contact)
            axes[row, 2 * i].set_title(f"{side}: {p.name} ({p.group})", fontsize=6)
            d = np.clip(np.abs(p.contact.astype(float) - p.no_contact) * 8, 0, 255)
            axes[row, 2 * i + 1].imshow(d.astype(np.uint8))
            axes[row, 2 * i + 1].set_title("|contact - no contact| x8", fontsize=6)
    for a in axes[:, :2 * k].ravel():
        a.axis("off")
    rk = ranking
    if rk:
        ax = axes[0, -1]
        names = list(rk["settings"])
        xs = [rk["settings"][n]["sim"]["accuracy"] for n in names]
        ys = [rk["settings"][n]["real"]["accuracy"] for n in names]
        ax.scatter(xs, ys, s=8)
        for n, x, y in zip(names, xs, ys, strict=True):
            ax.annotate(n, (x, y), fontsize=4)
        ax.plot([0, 1], [0, 1], lw=0.5, color="grey")
        sp = rk["accuracy_spearman"]
        ax.set_title(f"rho {sp['rho']:.2f} [{sp['ci95'][0]:.2f}, {sp['ci95'][1]:.2f}]",
                     fontsize=6)
        ax.set_xlabel(f"sim accuracy (+{rk['budget']} touches)", fontsize=6)
        ax.set_ylabel("real accuracy", fontsize=6)
        ax.tick_params(labelsize=5)
        axes[1, -1].axis("off")
    return _save(fig, path)


def library_curve(path: Path, results: dict) -> Path:
    """``tactex experiment library``: right at the stop (Wilson 95 %) and touches after the
    baseline per block of trial positions, learning off and each learning arm; one column per
    replay library (``results``: {library: its results with ``summary.curve`` and ``arms``})."""
    plt = _plt()
    names = list(results)
    fig, axes = plt.subplots(2, len(names), figsize=(5.5 * len(names), 7), squeeze=False)
    for j, name in enumerate(names):
        cur = results[name]["summary"]["curve"]
        xs = [np.mean(c["trials"]) for c in cur]
        # six marker styles: arms past the sixth are not drawn
        styles = ("o--", "s-", "^-", "v-", "d-", "x-")
        for arm, style in zip(results[name]["arms"], styles, strict=False):
            acc = [c["all"][arm]["accuracy"] for c in cur]
            lo = [a - c["all"][arm]["accuracy_ci95"][0] for a, c in zip(acc, cur, strict=True)]
            hi = [c["all"][arm]["accuracy_ci95"][1] - a for a, c in zip(acc, cur, strict=True)]
            axes[0, j].errorbar(xs, acc, yerr=[lo, hi], fmt=style, capsize=3,
                                label=f"learning {arm}")
            axes[1, j].plot(xs, [c["all"][arm]["touches_mean"] for c in cur], style,
                            label=f"learning {arm}")
        axes[0, j].plot(xs, [c["reference_known_share"] for c in cur], ":", color="grey",
                        label="reference fabric seen before")
        axes[0, j].set_title(f"{name} ({results[name]['sessions']} sessions)")
        axes[0, j].set_ylabel("right at stop (Wilson 95 %)")
        axes[0, j].set_ylim(0, 1.05)
        axes[1, j].set_ylabel("touches after the baseline")
        axes[1, j].set_xlabel("trial of the session")
        axes[0, j].legend(loc="lower right", fontsize=8)
    return _save(fig, path)
