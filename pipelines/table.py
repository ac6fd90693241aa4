"""`ncbot table`: the paper-style results table (mean ± std over seeds, the paper's numbers beside ours) and
learning-curve PNGs per agent, read from the run folders of `ncbot ablate`.

Runs are found as RUNS_DIR/<suite>/<game row>/<agent cell>/seed<N>/eval.json. The table reports the robot-first
seat (the paper's set-up) and adds the robot-second task success.
"""
from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

# Paper (Cuayahuitl 2019) table: (avg reward per action, task success, dialogue length); paper-notes section 5.
PAPER = {
    ("standard", "dqn_original-notemporal"): (0.0658, 0.8258, 13.93),
    ("standard", "dqn_variant-notemporal"): (0.5530, 0.9720, 13.99),
    ("standard", "proposed-notemporal"): (0.4710, 0.9868, 15.31),
    ("standard", "proposed-temporal"): (0.6300, 0.9980, 14.06),
    ("ultimate100", "dqn_original-notemporal"): (-0.6900, 0.7873, 63.54),
    ("ultimate100", "dqn_variant-notemporal"): (0.0177, 0.9074, 64.82),
    ("ultimate100", "proposed-notemporal"): (0.0693, 0.9377, 63.62),
    ("ultimate100", "proposed-temporal"): (0.1440, 0.9753, 52.03),
    ("ultimate150", "dqn_original-notemporal"): (-0.1120, 0.7290, 65.49),
    ("ultimate150", "dqn_variant-notemporal"): (-0.0310, 0.8663, 70.57),
    ("ultimate150", "proposed-notemporal"): (0.0997, 0.9473, 59.69),
    ("ultimate150", "proposed-temporal"): (0.1640, 0.9846, 52.09),
}
GAME_LABELS = {"standard": "3x3 (100)", "ultimate100": "Ultimate (100)", "ultimate150": "Ultimate (150)"}
CELL_LABELS = {
    "dqn_original-notemporal": "DQN-Original", "dqn_variant-notemporal": "DQN-Variant",
    "proposed-notemporal": "Proposed, no temporal", "proposed-temporal": "Proposed + temporal",
}
GAME_ORDER = list(GAME_LABELS)
CELL_ORDER = list(CELL_LABELS)


def _mean_std(values: list[float]) -> str:
    """Mean ± sample std over seeds; a single seed has no spread to report, so it shows the value alone."""
    if not values:
        return "–"
    mean = sum(values) / len(values)
    if len(values) == 1:
        return f"{mean:.4f}"
    std = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
    return f"{mean:.4f} ± {std:.4f}"


def collect_runs(runs_dir: str | Path) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """(suite, game row, agent cell) -> finished runs' eval.json contents, seeds in order."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        raise FileNotFoundError(f"runs folder {str(runs_dir)!r} not found (expected the folder ncbot ablate wrote)")
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = defaultdict(list)
    for path in sorted(runs_dir.glob("*/*/*/seed*/eval.json")):
        suite, game, cell = path.relative_to(runs_dir).parts[:3]
        try:
            groups[(suite, game, cell)].append(json.loads(path.read_text()))
        except json.JSONDecodeError:
            continue  # eval.json is written atomically; a bad one is foreign, skip it
    if not groups:
        raise FileNotFoundError(f"no finished runs (*/*/*/seed*/eval.json) under {str(runs_dir)!r}")
    return groups


def _order(key: tuple[str, str, str]) -> tuple:
    suite, game, cell = key
    return (GAME_ORDER.index(game) if game in GAME_ORDER else 99, game,
            CELL_ORDER.index(cell) if cell in CELL_ORDER else 99, cell, suite != "fast", suite)


def render_table(groups: dict[tuple[str, str, str], list[dict[str, Any]]]) -> str:
    """Markdown: one row per (game, agent, suite), ours as mean ± std over seeds, the paper's numbers beside."""
    lines = [
        "| game (units) | agent | settings | seeds | frames | avg reward | task success | dialogue length "
        "| task success, robot second | train time (s) | paper avg reward | paper task success | paper length |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key in sorted(groups, key=_order):
        suite, game, cell = key
        runs = groups[key]
        first = [r["first"] for r in runs]
        paper = PAPER.get((game, cell))
        paper_cells = [f"{v:.4f}" if i < 2 else f"{v:.2f}" for i, v in enumerate(paper)] if paper else ["–"] * 3
        frames = sorted({r["frames"] for r in runs})
        lines.append(" | ".join([
            f"| {GAME_LABELS.get(game, game)}", CELL_LABELS.get(cell, cell), suite, str(len(runs)),
            "/".join(str(f) for f in frames),
            _mean_std([f["avg_reward"] for f in first]), _mean_std([f["task_success"] for f in first]),
            _mean_std([f["avg_length"] for f in first]),
            _mean_std([r["second"]["task_success"] for r in runs]),
            f"{sum(r['train_wall_time_s'] for r in runs) / len(runs):.0f}",
            *paper_cells,
        ]) + " |")
    return "\n".join(lines) + "\n"


def write_table(runs_dir: str | Path, out: str | Path | None = None) -> str:
    """Write the markdown table (default RUNS_DIR/table.md) and curves_<suite>_<game>.png next to it."""
    from pipelines.plots import plot_agent_curves

    runs_dir = Path(runs_dir)
    groups = collect_runs(runs_dir)
    text = render_table(groups)
    out = Path(out) if out else runs_dir / "table.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    by_plot: dict[tuple[str, str], dict[str, list]] = defaultdict(dict)
    for (suite, game, cell), runs in groups.items():
        by_plot[(suite, game)][CELL_LABELS.get(cell, cell)] = [r.get("history", []) for r in runs]
    for (suite, game), curves in by_plot.items():
        plot_agent_curves(curves, out.parent / f"curves_{suite}_{game}.png",
                          title=f"{GAME_LABELS.get(game, game)}, {suite} settings: mean over seeds, band min..max")
    return text
