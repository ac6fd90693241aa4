"""The batched engine of a game tabulated from its rules (``ncbot.envs.games.table.GameTable``).

Why the same shape as the 3x3 engine: a position's id is its board code (``Boards.codes[:, 0]``), so legal squares,
the next position, the board, the outcome and the one-step look-ahead are each one row gather, and the env takes the
same fast path it takes for 3x3 (``rows_by_code``). Position 0 is the empty start, so a reset is the fill with 0
every engine's state gets.
"""
from __future__ import annotations

from typing import Any

import torch

from ncbot.envs.core import REWARD_WIN
from ncbot.envs.engine.base import Boards, _Engine
from ncbot.envs.engine.tables import uniform_choice
from ncbot.envs.readings import Readings


class TabulatedEngine(_Engine):
    """Row gathers from a game's position table; see the module doc."""

    grids = 1

    def __init__(self, table: Any, readings: Readings = Readings()) -> None:
        super().__init__(readings)
        if readings.misread:
            raise ValueError(f"taken_squares=misread keeps a believed board the rules may never reach; game "
                             f"{table.game.name!r} is tabulated from its rules: use taken_squares never or refused")
        self.table, self.cells = table, table.cells
        self._legal = torch.from_numpy(table.legal).contiguous()
        self._boards = torch.from_numpy(table.boards).contiguous()
        self._outcome = torch.from_numpy(table.outcome).contiguous()
        self._next = torch.from_numpy(table.next).reshape(-1).contiguous()
        about_to = readings.about_to
        self._rewards = {p: torch.from_numpy(table.reward_rows(p, about_to)).contiguous() for p in (1, 2)}

    def legal(self, state: Boards, active: torch.Tensor | None = None) -> torch.Tensor:
        legal = self._legal.index_select(0, state.codes[:, 0])
        return legal if active is None else legal & active.unsqueeze(1)

    def random_legal(self, state: Boards, generator: torch.Generator) -> torch.Tensor:
        return uniform_choice(self.legal(state), generator)

    def play(self, state: Boards, cells: torch.Tensor, player: torch.Tensor | int, active: torch.Tensor | None = None) -> None:
        if active is None:
            active = torch.ones_like(cells, dtype=torch.bool)
        cells = torch.where(active, cells, 0)
        position = state.codes.select(1, 0)
        after = self._next.index_select(0, (position * self.cells + cells) * 2 + (self._as_player(player, cells) - 1))
        position.copy_(torch.where(active, after, position))
        state.board = self._boards.index_select(0, position)
        self._count_move(state, cells, active)
        state.outcome = self._outcome.index_select(0, position)

    def from_boards(self, boards: torch.Tensor, last_move: torch.Tensor | None = None) -> Boards:
        """State of ``boards`` (B, cells), the seat to move read from the mark counts; ValueError for a board the rules
        never reach (move order unknown: cells get order 1..n in index order)."""
        state = self.new(boards.shape[0])
        taken = boards != 0
        n_marks = taken.sum(1)
        for row, board in enumerate(boards.to(torch.int8)):
            ones, twos = int((board == 1).sum()), int((board == 2).sum())
            position = self.table.position(board.numpy(), 1 if ones <= twos else 2)
            if position < 0:
                raise ValueError(f"board {board.tolist()} never arises in game {self.table.game.name!r}")
            state.codes[row, 0] = position
        state.board = self._boards.index_select(0, state.codes[:, 0])
        state.n_marks, state.move_order = n_marks, taken.long().cumsum(1) * taken
        state.outcome = self._outcome.index_select(0, state.codes[:, 0])
        if last_move is not None:
            state.last_move = last_move.clone()
        return state

    def rows_by_code(self, player: int) -> tuple[torch.Tensor, torch.Tensor]:
        """(positions, cells) legal squares and the one-step rewards of ``player``, row = position id."""
        return self._legal, self._rewards[player]

    def winning_rows_by_code(self, player: int) -> torch.Tensor:
        """(positions, cells) bool ``player``'s set A under ``win_set`` (see ``StandardEngine``)."""
        if self.readings.win_set == "wins":
            return torch.from_numpy(self.table.wins[player]).contiguous()
        return (self._rewards[player] == REWARD_WIN).contiguous()

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        return self._rewards[player].index_select(0, state.codes[:, 0])

    def winning_squares(self, board: torch.Tensor, player: int) -> torch.Tensor:
        """(B, cells) bool: where ``player``, to move on ``board``, wins at once."""
        return self.table.board_rows(board, player, self.table.wins[player])
