"""A declared game (``ncbot.envs.declaration``): ``k`` in a line on a rows x cols board, optionally with gravity; its
rules, and the line-count engine and bitboards that play it, behind the ``Game`` protocol.

Why not tabulated like a plain ``BoardGame``: a 6x7 board has far too many positions to enumerate; the declared
engine counts marks on every winning line with one matmul instead (``ncbot.envs.engine.declared``).
"""
from __future__ import annotations

import re
from functools import cached_property

import torch

from ncbot.envs.core import COLUMN_LETTERS, DRAWN, EMPTY, HUMAN, ROBOT
from ncbot.envs.declaration import Declaration
from ncbot.envs.games.board_game import BoardGame
from ncbot.envs.games.symmetries import board_symmetries
from ncbot.envs.readings import Readings
from ncbot.envs.rules import NUMBER_WORDS, State

_SPOKEN = re.compile(r"(row|column)\s*(\w+)\s*,?\s*(?:and\s+)?(row|column)\s*(\w+)")


class DeclaredGame(BoardGame):
    """A declared game: ``k`` in a line on a rows x cols board; with ``gravity`` a mark drops to the lowest empty
    square of its column. A full board without a line draws."""

    def __init__(self, declaration: Declaration) -> None:
        self.declaration = declaration
        self.id, self.name, self.rows, self.cols = declaration.game, declaration.name, declaration.rows, declaration.cols
        self.gravity = declaration.gravity
        self.lines_through = tuple(tuple(line for line in declaration.lines if cell in line) for cell in range(self.n_cells))

    # -- rules ---------------------------------------------------------------------------------------------------
    def legal(self, s: State) -> list[int]:
        if s.result != 0:
            return []
        if not self.gravity:
            return [cell for cell in range(self.n_cells) if s.board[cell] == EMPTY]
        return sorted(cell for cell in map(lambda col: self._drop(s.board, col), range(self.cols)) if cell >= 0)

    def _drop(self, board: tuple[int, ...], col: int) -> int:
        """The lowest empty square of column ``col`` (-1 when the column is full)."""
        return next((r * self.cols + col for r in reversed(range(self.rows)) if board[r * self.cols + col] == EMPTY), -1)

    def result(self, board: tuple[int, ...], cell: int, mark: int) -> int:
        if any(all(board[c] == mark for c in line) for line in self.lines_through[cell]):
            return mark
        return DRAWN if EMPTY not in board else 0

    def _why_illegal(self, s: State, cell: int, legal: list[int]) -> str:
        lowest = self._drop(s.board, cell % self.cols)
        return (f"cell {self.cell_name(cell)} ({cell}) is not the lowest empty square of column "
                f"{COLUMN_LETTERS[cell % self.cols]}: a mark drops to {self.cell_name(lowest)}")

    def parse_cell(self, text: str) -> int:
        """Inverse of ``cell_name`` ("b3", case and spaces ignored), or spoken: "row two column three" (either order,
        digits or number words)."""
        spoken = _SPOKEN.fullmatch(" ".join(str(text).lower().split()))
        if spoken and spoken.group(1) != spoken.group(3):
            where = {spoken.group(1): spoken.group(2), spoken.group(3): spoken.group(4)}
            row, col = _number(where["row"]), _number(where["column"], COLUMN_LETTERS[: self.cols])
            if 1 <= row <= self.rows and 1 <= col <= self.cols:
                return (row - 1) * self.cols + col - 1
        cleaned = "".join(str(text).split()).lower()
        letters = COLUMN_LETTERS[: self.cols]
        if len(cleaned) == 2 and cleaned[0] in letters and cleaned[1] in "123456789"[: self.rows]:
            return (int(cleaned[1]) - 1) * self.cols + letters.index(cleaned[0])
        raise ValueError(
            f"{text!r} is not a cell of the {self.name} board: expected a column {letters[0]}-{letters[-1]} and a row "
            f"1-{self.rows}, e.g. {self.cell_name(self.cols + 1)}, or \"row two column three\""
        )

    def describe(self) -> str:
        return self.declaration.describe()

    # -- what the stack needs, from the line counts ------------------------------------------------------------
    def engine(self, readings: Readings = Readings()):
        from ncbot.envs.engine.declared import DeclaredEngine

        return DeclaredEngine(self.declaration, readings)

    @cached_property
    def _lines(self):
        return self.engine()  # the line counts the opponents and the threat planes read (readings play no part)

    def search_engine(self):
        from ncbot.envs.opponents.declared_bits import DeclaredBits

        return DeclaredBits(self.declaration)

    def solver(self) -> None:
        return None  # too many positions to solve exactly

    def winning_cells(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        return self._lines.winning_squares(boards, player)

    def rule_scores(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        """2 a square that wins, 1 a square that blocks the other side's line."""
        return 2 * self.winning_cells(boards, player).long() + self.winning_cells(boards, 3 - player).long()

    def symmetries(self) -> torch.Tensor:
        return board_symmetries(self.rows, self.cols, self.gravity)

    def threat_names(self) -> list[str]:
        width = len(str(self.n_cells - 1))
        return [f"{side}_threat[{c:0{width}d}]" for side in ("robot", "human") for c in range(self.n_cells)]

    def threat_planes(self, board: torch.Tensor, owners: torch.Tensor | None = None) -> torch.Tensor:
        """Robot threats, then human threats: the squares where that side would complete a line now."""
        return torch.cat([self.winning_cells(board, side) for side in (ROBOT, HUMAN)], dim=1).float()

    def __repr__(self) -> str:
        return f"DeclaredGame({self.declaration.describe()})"


def _number(word: str, letters: str = "") -> int:
    """1..9 from a digit, a number word or (a column) one of ``letters``; 0 (no cell) otherwise."""
    if word in NUMBER_WORDS:
        return NUMBER_WORDS.index(word) + 1
    if len(word) == 1 and word in letters:
        return letters.index(word) + 1
    return int(word) if len(word) == 1 and word in "123456789" else 0
