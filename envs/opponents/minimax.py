"""``minimax``: perfect play where a game has an exact solver (``Game.solver``), random among equally good moves.

3x3 reads one table of optimal moves over every board (``ncbot.envs.opponents.minimax_table``); a game tabulated from
its rules is solved by negamax over its positions (``ncbot.envs.games.table.TableSolver``). Games without a solver
(Ultimate, the declared boards: too large) refuse the name in one line.
"""
from __future__ import annotations

from ncbot.envs.opponents.base import Opponent, masked_uniform_choice, no_argument, register_opponent
from ncbot.envs.opponents.minimax_table import optimal_move_table, position_values  # noqa: F401  (re-exported)

import torch


class MinimaxOpponent(Opponent):
    """Exact play: never loses, takes a forced win whenever one exists; random among optimal cells."""

    name = "minimax"

    def __init__(self, game: str = "standard", free_move: str = "anywhere", seed: int = 0) -> None:
        super().__init__(game, free_move, seed)
        self.solver = self.rules.solver()
        if self.solver is None:
            raise ValueError(f"opponent 'minimax' needs a game small enough to solve exactly; {self.rules.name!r} is "
                             "too large: use 'mcts:N'")

    def _select(self, boards, last_move, legal, player, generator, owners):
        optimal = self.solver.optimal_cells(boards, player) & legal
        # a board outside the solver's reach (no optimal cell but legal ones) falls back to any legal cell
        choice_mask = torch.where(optimal.any(dim=1, keepdim=True), optimal, legal)
        return masked_uniform_choice(choice_mask, generator)


def _minimax_factory(arg, *, game, free_move, seed):
    no_argument("minimax", arg)
    return MinimaxOpponent(game, free_move, seed)


register_opponent("minimax", _minimax_factory)
