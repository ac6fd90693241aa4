"""``--game`` of the commands that load a checkpoint (``ncbot eval``, ``ncbot ladder``): naming a run's game class.

Why: a run of a game given as code (``env.game=my_pkg.games:Misere``) records the class's import path; loading the
run never imports it (a checkpoint never makes ncbot run code the user did not name). The user names it again with
``--game PATH`` and the command imports it; a ``--game`` that is not the run's game is one line.
"""
from __future__ import annotations

import os


def name_game(game: str | None, checkpoint: str | os.PathLike) -> None:
    """Import the game ``game`` names (the user names it here) and check it is the game ``checkpoint`` plays."""
    if game is None:
        return
    from ncbot.envs.games import check_game, load_game
    from ncbot.pipelines.checkpoint import load_checkpoint

    named = load_game(game).id
    recorded = ((load_checkpoint(checkpoint).get("config") or {}).get("env") or {}).get("game", "standard")
    trained = check_game(recorded)
    if trained != named:
        raise ValueError(f"--game {game} does not match the checkpoint, which plays {trained}; drop --game")
