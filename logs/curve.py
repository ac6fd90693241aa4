"""The learning curve rebuilt from `/episode` summaries alone (no checkpoints, no trainer state).

Training episodes give a moving average over `window` episodes against env steps; evaluation episodes are
grouped by the `env_steps` they were run at and give one point each (mean over that evaluation).
"""
from __future__ import annotations

from collections.abc import Callable
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.fileio import atomic_path
from ncbot.logs.reader import read_episodes


def curve_series(episodes: list[dict[str, Any]], window: int = 200) -> dict[str, dict[str, Any]]:
    """Per agent: train moving averages and eval points of task success, reward/step and length.

    Evaluation episodes logged without `env_steps` (e.g. the final test games) form one point at the end
    of that agent's training curve."""
    if window < 1:
        raise ValueError(f"window must be at least 1 episode, got {window}")
    grouped: dict[str, dict[str, list]] = defaultdict(lambda: {"train": [], "eval": []})
    for episode in episodes:
        if episode.get("phase") in ("train", "eval"):
            grouped[str(episode.get("agent"))][episode["phase"]].append(episode)
    series: dict[str, dict[str, Any]] = {}
    for label, phases in sorted(grouped.items()):
        entry: dict[str, Any] = {}
        train = phases["train"]
        final_x = 0.0
        if train:
            x = _steps_axis(train)
            final_x = float(x[-1])
            success = np.array([float(bool(e.get("task_success"))) for e in train])
            returns = np.array([float(e.get("return", 0.0)) for e in train])
            lengths = np.array([max(1, int(e.get("length", 1))) for e in train], dtype=float)
            size = min(window, len(train))
            entry["train"] = {"x": x[size - 1:], "task_success": _moving(success, size),
                              "reward_per_step": _moving(returns, size) / _moving(lengths, size),
                              "length": _moving(lengths, size)}
        evaluation = phases["eval"]
        if evaluation:
            points: dict[float, list] = defaultdict(list)
            for e in evaluation:
                points[float(e["env_steps"]) if e.get("env_steps") is not None else final_x].append(e)
            xs = sorted(points)
            entry["eval"] = {
                "x": np.array(xs, dtype=float),
                "task_success": np.array([np.mean([bool(e.get("task_success")) for e in points[k]]) for k in xs]),
                "reward_per_step": np.array([sum(float(e.get("return", 0)) for e in points[k])
                                             / max(1, sum(int(e.get("length", 0)) for e in points[k])) for k in xs]),
                "length": np.array([np.mean([int(e.get("length", 0)) for e in points[k]]) for k in xs]),
                "games": [len(points[k]) for k in xs],
            }
        series[label] = entry
    return series


def _steps_axis(episodes: list[dict[str, Any]]) -> np.ndarray:
    """env_steps when logged, else the running sum of episode lengths. All episodes of one collector batch
    carry the same env_steps; they are spread evenly over that batch's frames so the curve has no steps."""
    if not all(e.get("env_steps") is not None for e in episodes):
        return np.cumsum([float(e.get("length", 0)) for e in episodes])
    logged = np.array([float(e["env_steps"]) for e in episodes])
    x = logged.copy()
    start, previous = 0, 0.0
    while start < len(logged):
        end = start
        while end + 1 < len(logged) and logged[end + 1] == logged[start]:
            end += 1
        count = end - start + 1
        x[start:end + 1] = previous + (logged[start] - previous) * np.arange(1, count + 1) / count
        previous, start = logged[start], end + 1
    return x


def _moving(values: np.ndarray, size: int) -> np.ndarray:
    cumulative = np.concatenate([[0.0], np.cumsum(values)])
    return (cumulative[size:] - cumulative[:-size]) / size


def plot_learning_curve(path: str | Path, output: str | Path, window: int = 200,
                        progress: Callable[..., Any] | None = None) -> dict[str, dict[str, Any]]:
    """Draw task success, reward per step and dialogue length against env steps into a PNG (atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output = Path(output)
    if output.suffix.lower() != ".png":
        raise ValueError(f"the curve is written as PNG; give an output path ending in .png, got {output}")
    series = curve_series(read_episodes(path, progress=progress), window)
    if not series:
        raise ValueError(f"{path} has no train or eval episodes to draw a learning curve from")
    figure, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    metrics = (("task_success", "task success (win or draw)"), ("reward_per_step", "average reward per step"),
               ("length", "dialogue length (actions)"))
    for index, (label, entry) in enumerate(series.items()):
        colour = f"C{index % 10}"
        for axis, (metric, title) in zip(axes, metrics):
            if "train" in entry:
                axis.plot(entry["train"]["x"], entry["train"][metric], color=colour, alpha=0.6, lw=1,
                          label=f"{label} train (moving avg {window})")
            if "eval" in entry:
                axis.plot(entry["eval"]["x"], entry["eval"][metric], "o-", color=colour, lw=2, ms=4,
                          label=f"{label} eval (mean per evaluation)")
            axis.set_title(title)
            axis.set_xlabel("env steps")
            axis.grid(alpha=0.3)
    axes[0].set_ylim(-0.02, 1.02)
    axes[0].legend(fontsize=7, loc="lower right")
    figure.suptitle(f"learning curve from {Path(path).name}")
    figure.tight_layout()
    try:
        with atomic_path(output) as temporary:
            figure.savefig(temporary, dpi=110, format="png")
    finally:
        plt.close(figure)
    return series
