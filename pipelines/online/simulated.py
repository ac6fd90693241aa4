"""Games against a simulated person without the robot's body: the dialogue env alone, logged like robot games.

Why: play learns from the logged transitions of the games it plays; what it learns does not depend on the camera
(the robot's eyes are the reader's business), so the play learner can be measured over many games and seeds here,
against any opponent model, in milliseconds per game instead of a minute of rendering. The games are written by the
same logger, phase "robot", per action, so `ncbot.pipelines.online.logged.read_games` reads them back exactly as it
reads `ncbot robot play`'s.
"""
from __future__ import annotations

from typing import Any


def play_logged_game(config: Any, policy: Any, logger: Any, *, opponent: str, seed: int, first: str,
                     agent_name: str) -> str:
    """One greedy game of `policy` against `opponent` (robot | human opening), logged; returns the outcome name."""
    from torchrl.envs.utils import ExplorationType, set_exploration_type, step_mdp

    from ncbot.envs.core import OUTCOME_NAMES
    from ncbot.pipelines.run_env import make_run_env

    env = make_run_env(config.env, batch_size=1, seed=seed, first=first, opponent=opponent)
    moves: list[list[int]] = []  # (cell, player) as a robot game's summary keeps them (`settled_moves`)
    try:
        td = env.reset()
        board = td["board"][0].tolist()  # a person who opens has made their first move in the reset
        moves.extend([cell, 2] for cell, value in enumerate(board) if value == 2)
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            while True:
                td = env.step(policy(td))
                after = td["next", "board"][0].tolist()
                for player in (1, 2):  # the robot's mark first, then the person's reply within the same step
                    moves.extend([cell, player] for cell, (a, b) in enumerate(zip(board, after)) if b == player != a)
                board = after
                done = bool(td["next", "done"].item())
                logger.record_steps(td, phase="robot", agent=agent_name, seed=seed, env=env,
                                    extra={"settled_moves": moves} if done else None)
                if done:
                    return OUTCOME_NAMES[int(td["next", "outcome"].item())]
                td = step_mdp(td)
    finally:
        env.close()
