"""`ncbot reproduce budget`: the title's data-efficiency claim as curves (how much data each part needs).

- dialogues: the act filter learnt from k of the paper set's example dialogues (k in 1, 2, 4, 8, 12; 3 seeded
  subsets each) against the filter of the whole set: the share of the whole set's example turns whose allowed
  acts are the same set under both filters. (k = 24 needs a second dozen in the paper's shape: not in the data.)
  The trained agent per k is not measured yet (it needs an env option that learns from a subset).
- games: task success against training games, read off the `table` runs' periodic greedy evaluations (the first
  one at or after each point): a run capped at N games is the same run stopped there, because every schedule
  (epsilon, target updates) counts frames, not games.
- vision: the cell classifier trained on N labelled cells, scored on held-out handwriting
  (pipelines/reproduce_vision.py; its section and `data_budget_vision.png` come from there).
"""
from __future__ import annotations

import json
import random
from collections import defaultdict
from pathlib import Path
from typing import Any

from fileio import atomic_write_text
from pipelines.claims import CELL_LABELS, GAME_LABELS

DIALOGUE_POINTS = (1, 2, 4, 8, 12)
SUBSETS = 3
PAPER_DIALOGUES = 12  # the paper's "a dozen dialogues" per game
DIALOGUE_AGENT_NOT_YET = "not yet: training an agent on k example dialogues needs an env option that learns from a subset"


def filter_agreement(game: str, k: int, seed: int, dialogues: str = "paper") -> float:
    """Share of the whole set's example turns whose allowed acts (Pr > 0.001) the filter from a seeded subset of
    ``k`` dialogues allows exactly as the whole set's filter does."""
    import envs.dialogue as dlg

    chosen = dlg.dialogue_set(dialogues)
    examples = dlg.load_dialogues(game, chosen.path)
    if not 1 <= k <= len(examples):
        raise ValueError(f"k must be between 1 and {len(examples)} example dialogues, got {k}")
    full = dlg.build_dialogue_model(game, dialogues)
    subset = dlg.fit_dialogue_model(game, random.Random(seed).sample(examples, k), chosen)
    same = [bool((full.filter_allowed[c] == subset.filter_allowed[c]).all()) for c in full.example_contexts]
    return sum(same) / len(same)


def dialogue_budget(games: tuple[str, ...]) -> list[dict[str, Any]]:
    """One record per (game, k): the mean agreement over the seeded subsets (a single subset at k = all)."""
    records = []
    for game in games:
        for k in DIALOGUE_POINTS:
            seeds = 1 if k == PAPER_DIALOGUES else SUBSETS
            values = [filter_agreement(game, k, seed) for seed in range(seeds)]
            records.append({"game": game, "dialogues": k, "subsets": seeds, "filter_agreement": sum(values) / seeds,
                            "task_success": None, "avg_length": None})
    return records


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
    from pipelines.plots import pyplot, save_figure

    plt = pyplot()
    paths = []
    fig, ax = plt.subplots(figsize=(6, 4))
    for game in sorted({r["game"] for r in dialogues}):
        rows = [r for r in dialogues if r["game"] == game]
        ax.plot([r["dialogues"] for r in rows], [r["filter_agreement"] for r in rows], marker="o", label=game)
    ax.axvline(PAPER_DIALOGUES, color="grey", linestyle="--", label="paper: a dozen")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("example dialogues")
    ax.set_ylabel("act filter agreement with all 12")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(label[:90], fontsize=7)
    paths.append(save_figure(fig, out / "data_budget_dialogues.png"))
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


def render_budget(data: dict[str, Any], command: str, label: str) -> str:
    lines = ["# Data budgets (the title's claim: a dozen dialogues, a few hundred images)", "", f"> {label}", "",
             f"Made by `{command}`. Figures: `data_budget_dialogues.png`, `data_budget_games.png`.", "",
             "## Vision: labelled cell images", "", data["vision_markdown"].rstrip(), "",
             "## Dialogues: example dialogues per game (paper set)", "",
             f"Act filter agreement: share of the 12 dialogues' system turns whose allowed acts are the same under the "
             f"filter learnt from k dialogues (mean over {SUBSETS} seeded subsets) as under all 12. Agent columns: "
             f"{DIALOGUE_AGENT_NOT_YET}.", "",
             "| game | dialogues | subsets | filter agreement | task success | dialogue length |", "|---|---|---|---|---|---|"]
    for r in data["dialogues"]:
        lines.append(f"| {r['game']} | {r['dialogues']} | {r['subsets']} | {r['filter_agreement']:.3f} | not yet | not yet |")
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


def write_budget_report(budget: Any, *, runs_dir: Path, out: Path, command: str) -> dict[str, Any]:
    """Write out/data_budget.md and its PNGs; return the `--json` object {vision, dialogues, games} (+ label)."""
    games_of_rows = tuple(dict.fromkeys("standard" if row == "standard" else "ultimate" for row in budget.rows))
    from pipelines.reproduce_vision import vision_budget_part

    data = {"label": budget.label, "command": command,
            **vision_budget_part(budget, runs_dir=Path(runs_dir), out=out, command=command),
            "dialogues": dialogue_budget(games_of_rows), "games": games_budget(Path(runs_dir), budget.game_points)}
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(render_budget(data, command, budget.label), out / "data_budget.md")
    data["figures"] = [str(p) for p in _plot(data["dialogues"], data["games"], out, budget.label)]
    data["figures"] += data.pop("vision_figures")
    return data
