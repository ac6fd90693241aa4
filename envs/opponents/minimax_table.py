"""Perfect 3x3 play as a table: the optimal moves of every board, seen from the side to move (``minimax``'s 3x3 solver).

The table is built once per process by negamax over all 3^9 boards seen from the side to move (so it also
answers for boards the env reaches with the robot or the human moving first), then each decision is one
gather: boards -> base-3 index -> 9-bit mask of optimal cells.
"""
from __future__ import annotations

from functools import lru_cache

import torch

from ncbot.envs.core import LINES_3X3

POWERS_OF_3 = torch.tensor([3**i for i in range(9)], dtype=torch.long)


def _has_line(board: tuple[int, ...], mark: int) -> bool:
    return any(board[a] == mark == board[b] == board[c] for a, b, c in LINES_3X3)


def _child(board: tuple[int, ...], cell: int) -> tuple[int, ...]:
    """The board after the side to move (1) takes ``cell``, relabelled so that the new side to move is 1 again."""
    return tuple(2 if m == 1 or i == cell else 1 if m == 2 else 0 for i, m in enumerate(board))


def _solve(board: tuple[int, ...], memo: dict[tuple[int, ...], int], best_cells: dict[tuple[int, ...], list[int]]) -> int:
    """Negamax value for the side to move (mark 1): +1 win, 0 draw, -1 loss; records the optimal cells."""
    if board in memo:
        return memo[board]
    if _has_line(board, 2):
        value = -1
    elif 0 not in board:
        value = 0
    else:
        values = {cell: -_solve(_child(board, cell), memo, best_cells) for cell in range(9) if board[cell] == 0}
        value = max(values.values())
        best_cells[board] = [cell for cell, v in values.items() if v == value]
    memo[board] = value
    return value


@lru_cache(maxsize=1)
def _solved() -> tuple[dict[tuple[int, ...], int], dict[tuple[int, ...], list[int]]]:
    """Values and optimal cells of every board reachable by alternating play, seen from the side to move."""
    memo: dict[tuple[int, ...], int] = {}
    best_cells: dict[tuple[int, ...], list[int]] = {}
    _solve((0,) * 9, memo, best_cells)
    return memo, best_cells


@lru_cache(maxsize=1)
def optimal_move_table() -> torch.Tensor:
    """(3^9, 9) bool: for each board (1 = side to move, 2 = other side) the cells of optimal value.

    Boards that are decided (a line present, or full) or unreachable by alternating play have no optimal cells.
    """
    table = torch.zeros(3**9, 9, dtype=torch.bool)
    for board, cells in _solved()[1].items():
        table[sum(m * 3**i for i, m in enumerate(board)), cells] = True
    return table


def position_values(boards: torch.Tensor, player: int) -> torch.Tensor:
    """(B,) int64 game values (+1/0/-1) for ``player`` to move on each 3x3 board (handy for tests and ladders)."""
    values = _solved()[0]
    relabelled = _relabel(boards, player)
    try:
        return torch.tensor([values[tuple(row)] for row in relabelled.tolist()], dtype=torch.long)
    except KeyError as missing:
        raise ValueError(f"board {list(missing.args[0])} cannot arise in alternating play with player {player} to move") from None


def _relabel(boards: torch.Tensor, player: int) -> torch.Tensor:
    """Boards with the mover as 1 and the other side as 2."""
    boards = boards.long()
    if player == 1:
        return boards
    return torch.where(boards == 0, boards, 3 - boards)


class NoughtsCrossesSolver:
    """The 3x3 game's exact solver (``Game.solver``): the optimal cells of every board from one table gather."""

    def optimal_cells(self, boards: torch.Tensor, player: int) -> torch.Tensor:
        """(B, 9) bool the cells of optimal value for ``player`` to move (none on a decided or unreachable board)."""
        return optimal_move_table()[(_relabel(boards, player) * POWERS_OF_3).sum(dim=1)]
