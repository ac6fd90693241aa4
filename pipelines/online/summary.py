"""What a learning run achieved, before against after: the reader on held-out handwriting, the play against the
random user and against the person, and the game-by-game figure (PNG).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ncbot.pipelines.online.learning import PersonLearning
from ncbot.pipelines.plots import pyplot, save_figure

TEST_GAMES = 600     # per opponent, both seats, for the play's before / after
TEST_SEED = 8_000_009  # apart from the gate's games and from training and evaluation seeds
OUTCOME_COLOURS = {"win": "tab:green", "draw": "tab:blue", "loss": "tab:red", "unfinished": "tab:gray"}


def reader_before_after(learning: PersonLearning, styles: list[str]) -> dict[str, Any] | None:
    """Share of cells read right per handwriting style (the person's and the budget's held-out ones), by the reader
    the run started with and by the reader it ends with."""
    if learning.reader is None:
        return None
    from ncbot.vision.classifier import load_classifier
    from ncbot.vision.online.heldout import accuracy_by_style, style_cells
    from ncbot.vision.strokes import HELDOUT_STYLES

    cells = {style: style_cells(style) for style in dict.fromkeys([*styles, *HELDOUT_STYLES])}
    before = accuracy_by_style(load_classifier(learning.reader.folder / "start.pt"), cells)
    after = accuracy_by_style(learning.reader.classifier, cells)
    return {"cells_per_style": len(next(iter(cells.values()))[1]),
            "accuracy": {style: {"before": round(before[style], 4), "after": round(after[style], 4)} for style in cells}}


def play_before_after(learning: PersonLearning, opponents: list[str], games: int = TEST_GAMES) -> dict[str, Any] | None:
    """Greedy test games of the starting and the final agent against each opponent (both seats)."""
    if learning.play is None:
        return None
    from ncbot.pipelines.online import agent_parts

    play = learning.play
    start_config, start_data = agent_parts.load_saved_agent(play.folder / "start.pt")
    start_qnet, start_policies, _ = agent_parts.build_agent(start_config, start_data, 0)
    result = {}
    for opponent in dict.fromkeys(["random", *opponents]):
        rows = {}
        for name, policy in (("before", start_policies.greedy), ("after", play.policy)):
            tested = agent_parts.test_games(play.config, policy, games, TEST_SEED, opponent=opponent)
            rows[name] = {"win": round(tested.win, 4), "draw": round(tested.draw, 4), "loss": round(tested.loss, 4),
                          "task_success": round(tested.task_success, 4)}
        result[opponent] = rows
    return {"games_per_opponent": games, "results": result}


def draw_learning(per_game: list[dict[str, Any]], reader: dict[str, Any] | None, path: str | Path,
                  title: str) -> Path:
    """Game by game: misread and unseen moves with the outcome above each game; the reader's check errors before
    and after each update (kept or rolled back); held-out accuracy before -> after in the legend."""
    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    games = [entry["game"] for entry in per_game]
    misread = [entry.get("misrecognised_moves") or 0 for entry in per_game]  # None: a game without the camera
    unseen = [entry.get("unseen_moves") or 0 for entry in per_game]
    top.bar(games, misread, color="tab:red", label="misread moves")
    top.bar(games, unseen, bottom=misread, color="tab:orange", label="unseen moves")
    ceiling = max([a + b for a, b in zip(misread, unseen)] + [1]) + 0.6
    for game, entry in zip(games, per_game):
        outcome = entry.get("outcome", "unfinished")
        top.scatter([game], [ceiling], color=OUTCOME_COLOURS.get(outcome, "black"), marker="s", s=30)
    top.set_ylim(0, ceiling + 0.6)
    top.set_ylabel("moves")
    top.legend(loc="upper left", fontsize=8)
    top.set_title(f"{title}\n(squares: outcome, green win, blue draw, red loss, grey unfinished)", fontsize=9)
    updates = [(entry["game"], entry["reader"]) for entry in per_game if entry.get("reader", {}).get("updated")]
    if updates:
        xs = [game for game, _ in updates]
        bottom.plot(xs, [r["check_errors_before"] for _, r in updates], "o--", color="tab:gray", label="before update")
        bottom.plot(xs, [r["check_errors_after"] for _, r in updates], "o-", color="tab:purple", label="after update")
        rolled = [(game, r["check_errors_after"]) for game, r in updates if not r["kept"]]
        if rolled:
            bottom.scatter(*zip(*rolled), marker="x", s=80, color="tab:red", label="rolled back", zorder=3)
    bottom.set_ylabel("reader errors on its check set")
    bottom.set_xlabel("game")
    if reader is not None:
        text = "held-out cells read right, before -> after:\n" + "\n".join(
            f"{style}: {100 * v['before']:.1f}% -> {100 * v['after']:.1f}%" for style, v in reader["accuracy"].items())
        bottom.text(1.01, 0.5, text, transform=bottom.transAxes, fontsize=8, va="center")
    if bottom.get_legend_handles_labels()[0]:  # nothing drawn below (no reader update) names nothing
        bottom.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)
