"""`ncbot learn LOGS`: learning from robot games recorded earlier, game by game, exactly as if they were being played.

The reader's examples come from the logged camera frames of the robot's looks after settled moves (their times and
the agreed moves are in each game's `/episode` summary), the play's transitions from the logged steps, so a folder
learned offline from a run's log holds what the same run learning online would hold.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ncbot.pipelines.online.learning import LearnSettings, PersonLearning
from ncbot.pipelines.online.logged import LoggedGame, game_views, read_games, settled_moves
from ncbot.robot_sim.settlement import claim_moves

CLAIMS_SEED = 5_000_011  # the wrong claims `--wrong-claims` adds: their own stream


def logged_games(logs: list[Path]) -> list[LoggedGame]:
    """Every robot game of the logs, in the order given (each log in its own order)."""
    return [game for log in logs for game in read_games(log)]


def played(game: LoggedGame) -> dict[str, Any]:
    """How the game went, as the robot's report gives it (the true outcome, the moves it misread or missed)."""
    extra = game.extra
    return {"outcome": extra.get("true_outcome", game.summary.get("outcome")),
            "misrecognised_moves": extra.get("misrecognised_moves"), "unseen_moves": extra.get("unseen_moves"),
            "handwriting": (extra.get("conditions") or {}).get("handwriting", "pen"), "log_episode": game.episode}


def learn_from_logs(logs: list[Path], folder: Path, settings: LearnSettings, weights: Path | None,
                    checkpoint: Path | None, wrong_claims: float = 0.0, progress: Any = None) -> PersonLearning:
    """Learn from every logged game not learned yet (a folder that holds learning resumes after its games)."""
    from ncbot.robot_sim.scene import check_game

    games = logged_games(logs)
    learning = PersonLearning.open(folder, settings, weights=weights, checkpoint=checkpoint)
    rng = np.random.default_rng([CLAIMS_SEED, learning.games])
    bar = progress(total=len(games), initial=min(learning.games, len(games)), desc="learn from games",
                   unit="game") if progress else None
    for game in games[learning.games:]:
        grid = check_game(game.summary.get("game", "standard"))
        views, _ = game_views(game, grid)
        moves = claim_moves(settled_moves(game), len(views[0].cells) if views else 0, wrong_claims, rng)
        learning.learn(views, moves, game.summary.get("seat") == "first", game, played(game))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return learning
