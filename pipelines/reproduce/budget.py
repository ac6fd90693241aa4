"""`ncbot reproduce budget`: the title's data-efficiency claim as curves (how much data each part needs).

- dialogues (pipelines/reproduce/dialogues.py): the act filter learnt from k of the paper set's example dialogues
  (k in 1, 2, 4, 8, 12, 24; 13-24 are ours, authored) against the filter of all of them, and the 3x3 agent trained
  in the env learnt from k dialogues (`env.dialogue_subset`): its task success and dialogue length per k.
- games: task success against training games, read off the `table` runs' periodic greedy evaluations (the first
  one at or after each point): a run capped at N games is the same run stopped there, because every schedule
  (epsilon, target updates) counts frames, not games.
- vision: the cell classifier trained on N labelled cells, scored on held-out handwriting
  (pipelines/reproduce/vision.py; its section and `data_budget_vision.png` come from there).
"""
from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.reproduce.claims import CELL_LABELS, GAME_LABELS
from ncbot.pipelines.reproduce.dialogues import dialogue_records, dialogue_section, plot_dialogues



def _runs(runs_dir: Path) -> dict[tuple[str, str], list[list[dict[str, Any]]]]:
    """Periodic-evaluation histories per (game row, agent cell) of the finished runs under ``runs_dir``."""
    histories: dict[tuple[str, str], list[list[dict[str, Any]]]] = defaultdict(list)
    for path in sorted(runs_dir.glob("*/*/*/seed*/eval.json")):
        game, cell = path.parts[-4], path.parts[-3]
        histories[(game, cell)].append(json.loads(path.read_text()).get("history", []))
    return histories


def games_budget(runs_dir: Path, points: tuple[int, ...]) -> list[dict[str, Any]]:
    """Task success (robot alternating seats, the periodic evaluation) at each training-games point, mean over the
    seeds whose run reached it."""
    records = []
    for (game, cell), histories in sorted(_runs(runs_dir).items()):
        for games in points:
            reached = [next((h for h in history if h["episodes"] >= games), None) for history in histories]
            reached = [h for h in reached if h is not None]
            if not reached:
                continue
            records.append({"game": game, "agent": CELL_LABELS.get(cell, cell), "games": games, "seeds": len(reached),
                            "games_at_eval": [h["episodes"] for h in reached],
                            "task_success": sum(h["task_success"] for h in reached) / len(reached)})
    return records


def _plot(dialogues: list[dict], games: list[dict], out: Path, label: str) -> list[Path]:
    from ncbot.pipelines.plots import pyplot, save_figure

    plt = pyplot()
    paths = [plot_dialogues(dialogues, out / "data_budget_dialogues.png", label)]
    fig, axes = plt.subplots(1, max(1, len({r["game"] for r in games})), figsize=(12, 4), squeeze=False)
    for ax, game in zip(axes[0], sorted({r["game"] for r in games})):
        for agent in sorted({r["agent"] for r in games if r["game"] == game}):
            rows = [r for r in games if r["game"] == game and r["agent"] == agent]
            ax.plot([r["games"] for r in rows], [r["task_success"] for r in rows], marker="o", label=agent)
        ax.axvline(20_000, color="grey", linestyle="--", label="paper: 20K games")
        ax.set_xscale("log")
        ax.set_xlabel("training games")
        ax.set_ylabel("task success")
        ax.set_title(GAME_LABELS.get(game, game))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(label[:140], fontsize=7)
    paths.append(save_figure(fig, out / "data_budget_games.png"))
    return paths


def render_budget(data: dict[str, Any], command: str, label: str, budget: Any) -> str:
    lines = ["# Data budgets (the title's claim: a dozen dialogues, a few hundred images)", "", f"> {label}", "",
             f"Made by `{command}`. Figures: `data_budget_dialogues.png`, `data_budget_games.png`.", "",
             "## Vision: labelled cell images", "", data["vision_markdown"].rstrip(), "",
             *dialogue_section(data["dialogues"], budget)]
    lines += ["", "## Games: task success against training games (paper settings)", "",
              "Read off each run's periodic greedy evaluation (alternating seats) at the first evaluation at or after "
              "the point; mean over the seeds that reached it.", "",
              "| game (units) | agent | training games | seeds | games at the evaluation | task success |",
              "|---|---|---|---|---|---|"]
    for r in data["games"]:
        lines.append(f"| {GAME_LABELS.get(r['game'], r['game'])} | {r['agent']} | {r['games']} | {r['seeds']} | "
                     f"{', '.join(str(g) for g in r['games_at_eval'])} | {r['task_success']:.4f} |")
    if not data["games"]:
        lines.append("| – | no finished runs yet: run `ncbot reproduce table` first | | | | |")
    return "\n".join(lines) + "\n"


def write_budget_report(budget: Any, *, runs_dir: Path, out: Path, command: str,
                        dialogue_runs: Path | None = None) -> dict[str, Any]:
    """Write out/data_budget.md and its PNGs; return the `--json` object {vision, dialogues, games} (+ label).
    ``dialogue_runs``: the dialogue-budget agents' runs folder (pipelines/reproduce/dialogues.py)."""
    games_of_rows = budget.games
    from ncbot.pipelines.reproduce.vision import vision_budget_part

    data = {"label": budget.label, "command": command,
            **vision_budget_part(budget, runs_dir=Path(runs_dir), out=out, command=command),
            "dialogues": dialogue_records(games_of_rows, dialogue_runs),
            "games": games_budget(Path(runs_dir), budget.game_points)}
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(render_budget(data, command, budget.label, budget), out / "data_budget.md")
    data["figures"] = [str(p) for p in _plot(data["dialogues"], data["games"], out, budget.label)]
    data["figures"] += data.pop("vision_figures")
    return data
