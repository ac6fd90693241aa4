"""``mcts:N``: plain UCT with N simulations and uniformly random playouts, on any game's search positions.

The search itself is the shared loop of ``ncbot.envs.opponents.search`` (UCT selection, ``RandomRollout`` evaluator).

One search per game in the batch, each on the bitboard engines of ``bitboards.py`` (the random playouts are
the hot loop). Each decision draws one seed from the caller's torch generator for a private ``random.Random``,
so results are reproducible from the generator alone. The root's moves are the caller's legal cells: the
opponent never contradicts the env, even where the board alone leaves subgrid ownership ambiguous.
"""
from __future__ import annotations

import random

import torch

from ncbot.envs.opponents.base import Opponent, register_opponent, simulation_count
from ncbot.envs.opponents.search import UCT, RandomRollout, run_search

DEFAULT_EXPLORATION = 0.7  # UCB1 constant for rewards in [0, 1]; 0.5-0.7 beat 1.0-1.4 vs random at 100 sims (docs)


def uct_search(engine, pos: tuple, root_moves: list[int], simulations: int, rng: random.Random,
               exploration: float = DEFAULT_EXPLORATION) -> tuple[int, dict[int, tuple[int, float]]]:
    """Run ``simulations`` UCT iterations from ``pos``; the most visited root move and per-move (visits, win rate).

    The search loop of ``ncbot.envs.opponents.search`` with UCB1 selection and random-playout evaluation."""
    rand = rng.random
    policy = UCT(engine, exploration)
    root = policy.root(pos, root_moves)
    run_search(root, simulations, rand, policy, RandomRollout(engine))
    stats = {child.move: (child.visits, child.value / child.visits) for child in root.children}
    return policy.choose(root, rand), stats


class MCTSOpponent(Opponent):
    """UCT with ``simulations`` random playouts per decision (the paper's future work asks for MCTS opponents)."""

    def __init__(self, simulations: int, game: str = "standard", free_move: str = "anywhere", seed: int = 0,
                 exploration: float = DEFAULT_EXPLORATION) -> None:
        super().__init__(game, free_move, seed)
        if simulations < 1:
            raise ValueError(f"mcts needs at least 1 simulation, got {simulations}")
        self.simulations = int(simulations)
        self.exploration = float(exploration)
        self.engine = self.rules.search_engine()
        self.name = f"mcts:{self.simulations}"

    def _select(self, boards, last_move, legal, player, generator, owners):
        cells = torch.zeros(boards.shape[0], dtype=torch.long)
        has_move = legal.any(dim=1)
        seeds = torch.randint(0, 2**62, (boards.shape[0],), generator=generator).tolist()
        board_rows, last_moves, legal_rows = boards.tolist(), last_move.tolist(), legal.tolist()
        owner_rows = owners.tolist() if owners is not None else [None] * boards.shape[0]
        for row in torch.nonzero(has_move).flatten().tolist():
            root_moves = [cell for cell, ok in enumerate(legal_rows[row]) if ok]
            if len(root_moves) == 1:
                cells[row] = root_moves[0]
                continue
            pos = self.engine.from_board(board_rows[row], player, last_moves[row], owner_rows[row])
            move, _ = uct_search(self.engine, pos, root_moves, self.simulations, random.Random(seeds[row]), self.exploration)
            cells[row] = move
        return cells


def _mcts_factory(arg, *, game, free_move, seed):
    return MCTSOpponent(simulation_count("mcts", arg), game, free_move, seed)


register_opponent("mcts", _mcts_factory, usage="mcts:N")
