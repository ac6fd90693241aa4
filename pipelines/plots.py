"""Learning curves as PNG (matplotlib, Agg): what people look at after a run, like the paper's figures."""
from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_path

CURVES = (
    ("avg_reward", "avg reward / action"),
    ("task_success", "task success"),
    ("avg_length", "dialogue length"),
    ("train_loss", "training loss"),
)


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display on the machines we run on)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def frames_label(value: float, _position: Any = None) -> str:
    """Short tick labels for env-frame axes: 0, 250K, 1.5M (full numbers ran together on narrow panels)."""
    for factor, suffix in ((1e6, "M"), (1e3, "K")):
        if abs(value) >= factor:
            return f"{value / factor:.3g}{suffix}"
    return f"{value:.0f}"


def frames_axis(ax) -> None:
    """At most 6 ticks on an env-frames x axis, labelled 100K-style."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]))
    ax.xaxis.set_major_formatter(FuncFormatter(frames_label))


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Save a figure (PNG, or the format of the suffix) atomically so a crash never leaves half a picture; closes
    the figure."""
    path = Path(path)
    try:
        with atomic_path(path) as temp:
            fig.savefig(temp, dpi=dpi, bbox_inches="tight", format=path.suffix.lstrip(".") or "png")
    finally:
        pyplot().close(fig)
    return path


def _spans_decades(values: Sequence[float]) -> bool:
    """Whether the positive finite values cover more than one decade (a log axis then shows the shape)."""
    import math

    kept = [v for v in values if isinstance(v, (int, float)) and math.isfinite(v) and v > 0]
    return bool(kept) and max(kept) / min(kept) > 10


def plot_learning_curve(history: Sequence[dict[str, Any]], path: str | os.PathLike, title: str = "") -> Path:
    """Periodic-evaluation metrics and training loss, over env frames (left) and wall time (right), as a PNG."""
    return save_figure(learning_curve_figure(history, title), path)


def learning_curve_figure(history: Sequence[dict[str, Any]], title: str = ""):
    """The figure of `plot_learning_curve`: task success per seat where the history has them."""
    plt = pyplot()
    fig, axes = plt.subplots(len(CURVES), 2, figsize=(10, 9), sharex="col")
    frames = [h["frames"] for h in history]
    seconds = [h["wall_time"] for h in history]
    for row, (key, label) in enumerate(CURVES):
        lines = {"both seats": [h.get(key, float("nan")) for h in history]}
        if key == "task_success" and any("seats" in h for h in history):
            lines = {name.split(", ")[1]: [seat_value(h, seat) for h in history] for seat, name in SEAT_PANELS}
        for col, xs in enumerate((frames, seconds)):
            ax = axes[row, col]
            for name, values in lines.items():
                ax.plot(xs, values, marker="o", markersize=3, label=name if len(lines) > 1 else None)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(label)
            if key == "train_loss" and _spans_decades(lines["both seats"]):
                from matplotlib.ticker import LogLocator, NullFormatter

                # a loss over several decades: log scale, labels on whole decades only (they never overlap);
                # within a decade the linear axis reads better
                ax.set_yscale("log")
                ax.yaxis.set_major_locator(LogLocator(numticks=5))
                ax.yaxis.set_minor_formatter(NullFormatter())
            if key == "task_success":
                ax.axhline(0.995, color="grey", linestyle="--", linewidth=0.8)
                if len(lines) > 1:
                    ax.legend(fontsize=7)
    frames_axis(axes[-1, 0])  # sharex: the bottom axis sets the column's ticks
    axes[-1, 0].set_xlabel("env frames (robot actions)")
    axes[-1, 1].set_xlabel("wall time (s, shared 2-core machine)")
    fig.suptitle(title or "learning curve (greedy evaluation vs random user)")
    return fig


SEAT_PANELS = (("robot_first", "task success, robot first"), ("robot_second", "task success, robot second"))


def seat_value(record: dict[str, Any], seat: str, key: str = "task_success") -> float:
    """A periodic evaluation's metric for one seat; NaN where the record has no per-seat results."""
    return float(record.get("seats", {}).get(seat, {}).get(key, float("nan")))


def plot_agent_curves(curves: dict[str, list[list[dict[str, Any]]]], path: str | os.PathLike, title: str = "",
                      levels: dict[str, tuple[float, float]] | None = None) -> Path:
    """Task success robot first and robot second per agent: mean over seeds (line) and min..max band; x = env
    frames. ``levels``: agents without a curve (no learning), drawn as dashed lines at their (first, second) task
    success, so a reader sees what learning adds."""
    import numpy as np

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for name, runs in sorted(curves.items()):
        runs = [r for r in runs if r]
        if not runs:
            continue
        length = min(len(r) for r in runs)
        frames = np.array([h["frames"] for h in runs[0][:length]])
        for ax, (seat, _) in zip(axes, SEAT_PANELS):
            values = np.array([[seat_value(h, seat) for h in r[:length]] for r in runs])
            if np.isnan(values).all():
                continue
            (line,) = ax.plot(frames, values.mean(0), label=name)
            ax.fill_between(frames, values.min(0), values.max(0), alpha=0.2, color=line.get_color())
    for name, seat_levels in sorted((levels or {}).items()):
        for ax, level in zip(axes, seat_levels):
            ax.axhline(level, color="black", linestyle="--", linewidth=1, label=name)
    for ax, (_, label) in zip(axes, SEAT_PANELS):
        frames_axis(ax)
        ax.set_xlabel("env frames")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:  # a seat with no curve (no periodic evaluation) has nothing to name
            ax.legend(fontsize=7)
    axes[0].set_ylabel("task success (greedy periodic evaluation)")
    fig.suptitle(title or "learning curves per agent (mean over seeds, band = min..max)")
    return save_figure(fig, path)


def plot_run_profiles(panels: dict[str, dict[str, list[float]]], path: str | os.PathLike, title: str = "") -> Path:
    """Every run's task success, one panel per game row (and settings): the share of an agent's runs scoring above
    each threshold (a performance profile, Agarwal et al. 2021), so a reader sees each seed rather than a mean.
    ``panels``: panel title -> agent label -> one score per run; up to 3 panels a line."""
    import numpy as np

    from ncbot.pipelines.reproduce.aggregate import performance_profile

    plt = pyplot()
    titles = list(panels) or ["no runs"]
    columns = min(3, len(titles))
    lines = -(-len(titles) // columns)
    agents = sorted({agent for by_agent in panels.values() for agent in by_agent})
    colours = {agent: f"C{i % 10}" for i, agent in enumerate(agents)}  # one colour per agent on every panel
    fig, axes = plt.subplots(lines, columns, figsize=(4.5 * columns, 4.3 * lines), sharex=True, sharey=True,
                             squeeze=False)
    lowest = min((s for by_agent in panels.values() for runs in by_agent.values() for s in runs), default=0.0)
    thresholds = np.linspace(max(0.0, lowest - 0.02), 1.0, 400)  # one scale on every panel, to compare them
    for ax, title_of_panel in zip(axes.flat, titles):
        by_agent = panels.get(title_of_panel, {})
        for agent, runs in sorted(by_agent.items()):
            ax.step(thresholds, performance_profile(runs, thresholds), where="post", color=colours[agent],
                    label=f"{agent} ({len(runs)} runs)")
        ax.set_title(title_of_panel, fontsize=10)
        ax.grid(alpha=0.3)
        if by_agent:
            ax.legend(fontsize=7)
    for ax in axes.flat[len(titles):]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("share of runs above the threshold")
    for ax in axes.flat[max(0, len(titles) - columns):len(titles)]:  # the lowest panel of each column
        ax.set_xlabel("task success threshold, robot first")
        ax.xaxis.set_tick_params(labelbottom=True)
    fig.suptitle(title or "run-score distributions (performance profiles)")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_two_sides(sides: dict[str, tuple[Sequence[float], tuple[float, float, float]]], path: str | os.PathLike,
                   xlabel: str, title: str = "") -> Path:
    """Every run of two (or more) sets as a dot, one line a set, with the set's mean and 95 % interval as a bar:
    what a comparison over seeds rests on, so a reader sees the spread and any outlying seed, not only a p-value.
    ``sides``: label -> (one value per run, (mean, low, high))."""
    import numpy as np

    plt = pyplot()
    labels = list(sides)
    fig, ax = plt.subplots(figsize=(7.0, 1.2 + 0.9 * len(labels)))
    rng = np.random.default_rng(0)  # a fixed jitter: the same runs draw the same picture
    for row, label in enumerate(labels):
        values, (mean, low, high) = sides[label]
        y = len(labels) - 1 - row
        ax.scatter(values, y + rng.uniform(-0.12, 0.12, len(values)), s=28, color=f"C{row}", alpha=0.8,
                   label=f"{label}: {len(values)} runs", zorder=3)
        ax.errorbar([mean], [y - 0.3], xerr=[[mean - low], [high - mean]], fmt="D", color=f"C{row}", capsize=4,
                    zorder=2)
    ax.set_yticks(range(len(labels)), labels[::-1])
    ax.set_ylim(-0.7, len(labels) - 0.5)
    ax.set_xlabel(xlabel)
    ax.grid(axis="x", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title or "every run (dots), mean with its 95 % interval (bar)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)
