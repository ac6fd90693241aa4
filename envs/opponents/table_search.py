"""Search positions of a game tabulated from its rules (``ncbot.envs.games.table.GameTable``), for the MCTS loop.

Same interface and result codes as ``ncbot.envs.opponents.bitboards`` (sides 0 = to move in the given position, 1 the
other; ``ONGOING``, 0, 1, ``DRAW``). A position is ``(id, turn, seat of side 0)``; moves and results are reads of
Python lists made once from the table, so a random playout is a few list lookups per move.
"""
from __future__ import annotations

from typing import Any

from ncbot.envs.core import DRAWN
from ncbot.envs.opponents.declared_bits import DRAW, ONGOING


class TableSearch:
    """Tree-search positions over a position table."""

    def __init__(self, table: Any) -> None:
        self.table, self.n_cells = table, table.cells
        self._next = table.next.tolist()  # [id][cell][seat - 1]
        self._moves = [[int(c) for c in row.nonzero()[0]] for row in table.legal]
        self._outcome = table.outcome.tolist()
        self._boards = table.boards.tolist()

    def from_board(self, board: list[int], mover: int, last_move: int = -1, owners=None) -> tuple:
        """Position from a board of seat codes (0 empty) with the seat ``mover`` to move; ValueError when the rules
        never reach it."""
        position = self.table.position(list(board), mover)
        if position < 0:
            raise ValueError(f"board {list(board)} with seat {mover} to move never arises in game {self.table.game.name!r}")
        return (position, 0, mover)

    def result(self, pos: tuple) -> int:
        outcome = self._outcome[pos[0]]
        return ONGOING if outcome == 0 else DRAW if outcome == DRAWN else 0 if outcome == pos[2] else 1

    def turn(self, pos: tuple) -> int:
        return pos[1]

    def moves(self, pos: tuple) -> list[int]:
        return list(self._moves[pos[0]]) if self._outcome[pos[0]] == 0 else []

    def play(self, pos: tuple, cell: int) -> tuple:
        position, turn, seat0 = pos
        seat = seat0 if turn == 0 else 3 - seat0
        return (self._next[position][cell][seat - 1], turn ^ 1, seat0)

    def rollout(self, pos: tuple, rand) -> int:
        """Play uniformly random moves to the end; the result (0, 1 or DRAW)."""
        position, turn, seat0 = pos
        nxt, moves, outcome = self._next, self._moves, self._outcome
        while outcome[position] == 0:
            legal = moves[position]
            seat = seat0 if turn == 0 else 3 - seat0
            position = nxt[position][legal[int(rand() * len(legal))]][seat - 1]
            turn ^= 1
        return self.result((position, turn, seat0))

    def position_cells(self, pos: tuple) -> tuple[list[int], list[int]]:
        """The cells of the side to move and of the other side."""
        board = self._boards[pos[0]]
        seat = pos[2] if pos[1] == 0 else 3 - pos[2]
        return ([c for c, v in enumerate(board) if v == seat], [c for c, v in enumerate(board) if v and v != seat])
