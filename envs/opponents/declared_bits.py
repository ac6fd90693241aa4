"""The bitboard engine of a declared game for tree search: positions are two Python ints (one bit per cell).

Same interface and result codes as ``ncbot.envs.opponents.bitboards`` (sides 0 = to move in the given position, 1 the
other; ``ONGOING``, 0, 1, ``DRAW``): the MCTS loop of ``ncbot.envs.opponents.search`` runs on it unchanged. A move
is a win when one of the lines through its cell (precomputed as bitmasks) is full of the mover's bits; with gravity
the moves are the lowest empty cell of each column, kept as one "next free row" per column in the position.
Position: ``(bits0, bits1, turn, result, tops)`` with ``tops`` the lowest empty cell per column (-1 full; gravity
only, else ``()``).
"""
from __future__ import annotations

from ncbot.envs.declaration import Declaration

ONGOING, DRAW = -1, 2  # the search engines' result codes besides the sides 0 and 1 (``bitboards`` re-exports them)


class DeclaredBits:
    """A declared game (rows x cols, k in a line, optional gravity) on two bitmasks."""

    def __init__(self, declaration: Declaration) -> None:
        self.n_cells, self.cols, self.gravity = declaration.cells, declaration.cols, declaration.gravity
        self.full = (1 << self.n_cells) - 1
        masks = [sum(1 << c for c in line) for line in declaration.lines]
        self.lines_of = tuple(tuple(m for m in masks if m >> cell & 1) for cell in range(self.n_cells))

    def _wins(self, bits: int, cell: int) -> bool:
        return any(bits & line == line for line in self.lines_of[cell])

    def from_board(self, board: list[int], mover: int, last_move: int = -1, owners=None) -> tuple:
        """Position from a board of codes (0 empty, else the player's code); ``mover`` is the code to move."""
        bits0 = sum(1 << c for c in range(self.n_cells) if board[c] == mover)
        bits1 = sum(1 << c for c in range(self.n_cells) if board[c] not in (0, mover))
        won = lambda bits: any(self._wins(bits, c) for c in range(self.n_cells) if bits >> c & 1)  # noqa: E731
        result = 1 if won(bits1) else 0 if won(bits0) else DRAW if (bits0 | bits1) == self.full else ONGOING
        tops = ()
        if self.gravity:
            taken = bits0 | bits1
            tops = tuple(next((c for c in range(self.n_cells - self.cols + col, -1, -self.cols) if not taken >> c & 1), -1)
                         for col in range(self.cols))
        return (bits0, bits1, 0, result, tops)

    def result(self, pos: tuple) -> int:
        return pos[3]

    def turn(self, pos: tuple) -> int:
        return pos[2]

    def moves(self, pos: tuple) -> list[int]:
        if pos[3] != ONGOING:
            return []
        if self.gravity:
            return sorted(c for c in pos[4] if c >= 0)
        taken = pos[0] | pos[1]
        return [c for c in range(self.n_cells) if not taken >> c & 1]

    def play(self, pos: tuple, cell: int) -> tuple:
        bits0, bits1, turn, _, tops = pos
        if turn == 0:
            bits0 |= 1 << cell
            mine = bits0
        else:
            bits1 |= 1 << cell
            mine = bits1
        if self.gravity:
            col = cell % self.cols
            tops = tops[:col] + (cell - self.cols if cell >= self.cols else -1,) + tops[col + 1:]
        result = turn if self._wins(mine, cell) else DRAW if (bits0 | bits1) == self.full else ONGOING
        return (bits0, bits1, turn ^ 1, result, tops)

    def position_cells(self, pos: tuple) -> tuple[list[int], list[int]]:
        """The cells of the side to move and of the other side."""
        lists = tuple([c for c in range(self.n_cells) if bits >> c & 1] for bits in (pos[0], pos[1]))
        return lists if pos[2] == 0 else (lists[1], lists[0])

    def rollout(self, pos: tuple, rand) -> int:
        """Play uniformly random moves to the end; the result (0, 1 or DRAW)."""
        while pos[3] == ONGOING:
            moves = self.moves(pos)
            pos = self.play(pos, moves[int(rand() * len(moves))])
        return pos[3]
