"""Play opponents against each other with the exact rules: for tests, benchmarks and the ladder.

All games of a match advance in lockstep (the same side is to move in every unfinished game), so each ply
is one batched ``select`` call. Moves are applied through the game's exact rules, which therefore referee every
opponent: an illegal choice raises at once instead of skewing the statistics.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import time
from dataclasses import dataclass

import torch

from ncbot.envs.opponents.base import Opponent
from ncbot.envs.games import check_game, make_game


@dataclass(frozen=True)
class MatchResult:
    """Counts from the first player's point of view, plus cost figures for benchmarks."""

    first_wins: int
    second_wins: int
    draws: int
    games: int
    marks: int  # total marks placed over all games
    first_seconds: float  # time spent inside the first player's select calls
    second_seconds: float

    @property
    def first_score(self) -> float:
        """Win = 1, draw = 0.5, averaged over games (the ladder's score)."""
        return (self.first_wins + 0.5 * self.draws) / self.games

    @property
    def second_score(self) -> float:
        return (self.second_wins + 0.5 * self.draws) / self.games


def play_match(first: Opponent, second: Opponent, n_games: int, seed: int = 0, game: str | None = None,
               free_move: str | None = None, batch_size: int = 256,
               progress: Callable[..., Any] | None = None) -> MatchResult:
    """``n_games`` games with ``first`` moving first (board code 1) and ``second`` (code 2), in batches."""
    game = check_game(game) if game else first.game
    free_move = free_move or first.free_move
    if n_games < 1:
        raise ValueError(f"n_games must be at least 1, got {n_games}")
    if first.game != game or second.game != game:
        raise ValueError(f"both players must be built for game {game!r}; got {first.game!r} and {second.game!r}")
    rules = make_game(game, free_move)
    generator = torch.Generator().manual_seed(seed)
    totals = {"x": 0, "o": 0, "draw": 0}
    marks = 0
    seconds = [0.0, 0.0]
    bar = None
    if progress is not None:  # a bar factory with tqdm's signature (pipelines.progress.progress_bar)
        bar = progress(total=n_games, desc=f"{first.name} vs {second.name}", unit="game")
    for start in range(0, n_games, batch_size):
        states = [rules.new() for _ in range(min(batch_size, n_games - start))]
        ply = 0
        while True:
            active = [i for i, s in enumerate(states) if rules.outcome(s) is None]
            if not active:
                break
            mover = first if ply % 2 == 0 else second
            boards = torch.tensor([states[i].board for i in active], dtype=torch.int8)
            last_move = torch.tensor([states[i].last_move for i in active], dtype=torch.long)
            legal = torch.zeros(len(active), rules.n_cells, dtype=torch.bool)
            for row, i in enumerate(active):
                legal[row, rules.legal(states[i])] = True
            owners = torch.tensor([states[i].subgrids for i in active], dtype=torch.int8) if rules.subgrids else None
            began = time.perf_counter()
            cells = mover.select(boards, last_move, legal, 1 + ply % 2, generator, owners=owners)
            seconds[ply % 2] += time.perf_counter() - began
            for row, i in enumerate(active):
                states[i] = rules.play(states[i], int(cells[row]))
            ply += 1
        for s in states:
            totals[rules.outcome(s)] += 1
            marks += s.n_marks
        if bar is not None:
            bar.update(len(states))
    if bar is not None:
        bar.close()
    return MatchResult(totals["x"], totals["o"], totals["draw"], n_games, marks, seconds[0], seconds[1])
