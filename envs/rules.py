"""Exact rules of board games of marks, one state at a time: the shared machinery (``BoardRules``), Noughts & Crosses
(3x3) and Ultimate Noughts & Crosses (9x9).

This is the small, slow, obviously-correct reference every faster engine (the batched tensor engine of the
env, the MCTS bitboards of the opponents) is checked against. States are immutable and hashable so they can
key tables (minimax) and be shared between search branches without copying.

Cells are numbered ``row * cols + col`` on the full grid. Marks on the board are the ints
``EMPTY = 0``, ``X = 1``, ``O = 2``; x always moves first. A game with views the rest of the stack derives
(engine, opponents, dialogue, sheet) is a ``ncbot.envs.games.BoardGame``; this module is only the rules. In Ultimate the nine subgrids are numbered the
same way (``subgrid = (row // 3) * 3 + col // 3``), and a move in cell position ``(row % 3, col % 3)`` of
its subgrid sends the opponent to subgrid ``(row % 3) * 3 + col % 3``.

Ultimate subtleties (documented in docs/rules.md):
- A subgrid is owned by whoever first completes a line in it; with ``free_move="anywhere"`` squares of a
  decided subgrid can still be taken, but that never changes its owner. A full subgrid without an owner
  is drawn. Drawn subgrids count for nobody in the line of subgrids.
- Because ownership depends on the order of play, it is part of the state (``State.subgrids``), not
  derived from the board alone.
- The game is won by the first line of three subgrids owned by the same player; it is drawn when the
  player to move has no legal square and no such line exists.
"""
from __future__ import annotations

import operator
import re
from dataclasses import dataclass
from typing import Literal

from ncbot.envs.core import (  # noqa: F401  (re-exported: the rules' public vocabulary)
    COLUMN_LETTERS, DRAWN, EMPTY, FREE_MOVE_CHOICES, LINES_3X3, O, SUBGRID_CELLS, SUBGRID_OF_CELL, TARGET_OF_CELL, X,
    check_free_move, subgrid_cells,
)

MARK_NAMES = {X: "x", O: "o"}
RESULT_NAMES = {0: None, X: "x", O: "o", DRAWN: "draw"}
_CELL = re.compile(r"([a-z])([1-9][0-9]?)")  # a column letter, a row number from 1
NUMBER_WORDS = ("one", "two", "three", "four", "five", "six", "seven", "eight", "nine")  # spoken rows and columns


def _has_line(marks: tuple[int, ...] | list[int], mark: int) -> bool:
    """True if ``mark`` fills one of the 8 lines of the 3x3 grid ``marks``."""
    return any(marks[a] == mark and marks[b] == mark and marks[c] == mark for a, b, c in LINES_3X3)


@dataclass(frozen=True)
class State:
    """One position: the board, the last move (-1 before the first), subgrid owners and the result.

    ``subgrids`` is empty for the 3x3 game; for Ultimate it holds 9 values (0 open, 1 x, 2 o, 3 drawn).
    ``result`` caches the outcome (0 none yet, 1 x won, 2 o won, 3 draw) so terminal tests are O(1).
    Build states with ``game.new()`` / ``game.play()``; hand-made ones are checked by ``game.validate``.
    """

    board: tuple[int, ...]
    last_move: int = -1
    subgrids: tuple[int, ...] = ()
    result: int = 0

    @property
    def n_marks(self) -> int:
        """Number of marks on the board (= moves played)."""
        return sum(1 for mark in self.board if mark != EMPTY)


class BoardRules:
    """What every game of marks on a rows x cols board shares: cell naming, turn order, move checking, rendering.

    A one-board game only says how a move ends it (``result``); a game whose state holds more than the board
    (Ultimate's subgrid owners) overrides ``new``, ``legal`` and ``_after`` too.
    """

    name: str
    rows: int
    cols: int

    @property
    def n_cells(self) -> int:
        return self.rows * self.cols

    @property
    def size(self) -> int:
        """Cells per row: cell = row * size + col."""
        return self.cols

    # -- basic queries -------------------------------------------------------------------------------
    def new(self) -> State:
        """The empty board, x to move."""
        return State(board=(EMPTY,) * self.n_cells)

    def legal(self, s: State) -> list[int]:
        """Cells the player to move may take, ascending; empty once the game is over. Default: every empty cell."""
        if s.result != 0:
            return []
        return [cell for cell in range(self.n_cells) if s.board[cell] == EMPTY]

    def result(self, board: tuple[int, ...], cell: int, mark: int) -> int:
        """How the game stands after ``mark`` (X or O) took ``cell``, ``board`` the board after the move: 0 still on,
        X or O the winner, DRAWN a draw. The one rule a one-board game must give."""
        raise NotImplementedError(f"{type(self).__name__} must say how a move ends the game: define result()")

    def _after(self, s: State, cell: int, board: tuple[int, ...], mark: int) -> State:
        return State(board=board, last_move=cell, result=self.result(board, cell, mark))

    def to_move(self, s: State) -> Literal["x", "o"]:
        """Whose turn it is: x when the number of marks is even."""
        return "x" if s.n_marks % 2 == 0 else "o"

    def mark_to_move(self, s: State) -> int:
        """Like ``to_move`` but as the board code (1 = x, 2 = o)."""
        return X if s.n_marks % 2 == 0 else O

    def outcome(self, s: State) -> Literal["x", "o", "draw"] | None:
        """None while the game goes on, else the winner ("x"/"o") or "draw"."""
        return RESULT_NAMES[s.result]

    def is_over(self, s: State) -> bool:
        return s.result != 0

    # -- moves ---------------------------------------------------------------------------------------
    def play(self, s: State, cell: int) -> State:
        """The state after the player to move takes ``cell``; ``s`` itself is unchanged.

        Raises ValueError (naming the cell and what is allowed) for out-of-range, taken, or otherwise
        illegal cells, and for any move after the game has ended.
        """
        try:
            cell = operator.index(cell)
        except TypeError:
            raise ValueError(f"cell must be an int in 0..{self.n_cells - 1}, got {cell!r}") from None
        if not 0 <= cell < self.n_cells:
            raise ValueError(f"cell {cell} is out of range: expected 0..{self.n_cells - 1} on the {self.name} board")
        if s.result != 0:
            raise ValueError(f"cell {self.cell_name(cell)} cannot be played: the game is over ({self.outcome(s)})")
        if s.board[cell] != EMPTY:
            raise ValueError(f"cell {self.cell_name(cell)} ({cell}) is already taken by {MARK_NAMES[s.board[cell]]}")
        legal = self.legal(s)
        if cell not in legal:
            raise ValueError(self._why_illegal(s, cell, legal))
        mark = self.mark_to_move(s)
        board = s.board[:cell] + (mark,) + s.board[cell + 1:]
        return self._after(s, cell, board, mark)

    def _why_illegal(self, s: State, cell: int, legal: list[int]) -> str:
        return f"cell {self.cell_name(cell)} ({cell}) is not legal here; legal cells: {legal}"

    def children(self, s: State) -> list[tuple[int, State]]:
        """Every legal move of ``s`` and the state it leads to (``play`` without its checks: the cells are legal)."""
        mark = self.mark_to_move(s)
        return [(cell, self._after(s, cell, s.board[:cell] + (mark,) + s.board[cell + 1:], mark)) for cell in self.legal(s)]

    def play_many(self, cells: list[int] | tuple[int, ...], s: State | None = None) -> State:
        """Play a sequence of cells from ``s`` (default: a new game); handy for tests and replays."""
        state = self.new() if s is None else s
        for cell in cells:
            state = self.play(state, cell)
        return state

    # -- naming and drawing --------------------------------------------------------------------------
    def cell_name(self, cell: int) -> str:
        """Human name of a cell: column letter then row number from 1 at the top, e.g. 4 -> "b2"."""
        return f"{COLUMN_LETTERS[cell % self.cols]}{cell // self.cols + 1}"

    def parse_cell(self, text: str) -> int:
        """Inverse of ``cell_name`` (case and spaces ignored); ValueError if not a cell. Every cell a person types or
        reads is written this one way (docs/design.md, CLI conventions)."""
        cleaned = "".join(str(text).split()).lower()
        letters = COLUMN_LETTERS[: self.cols]
        found = _CELL.fullmatch(cleaned)  # ASCII digits only: "²".isdigit() is True but int("²") fails
        if found and found.group(1) in letters:
            row = int(found.group(2)) - 1
            if 0 <= row < self.rows:
                return row * self.cols + letters.index(found.group(1))
        raise ValueError(
            f"{text!r} is not a cell of the {self.name} board: expected a column {letters[0]}-{letters[-1]} "
            f"and a row 1-{self.rows}, e.g. {self.cell_name(min(self.cols + 1, self.n_cells - 1))}"
        )

    def render(self, s: State, mark_legal: bool = False) -> str:
        """The board as text with coordinates (columns a.., rows 1.. from the top).

        Empty squares show as ``.``; with ``mark_legal`` the squares the player to move may take show as
        ``·`` and the other empty ones as a blank, which makes the Ultimate redirect visible.
        """
        return self.render_board(s.board, legal_cells=self.legal(s) if mark_legal else None)

    def render_board(self, board, symbols: dict[int, str] | None = None, legal_cells=None) -> str:
        """Draw any board of codes (e.g. the env's 1 robot / 2 human) with ``symbols`` for the codes.

        ``legal_cells`` (an iterable of cells) switches on the legal-square view of ``render``.
        """
        symbols = symbols or MARK_NAMES
        board = [int(v) for v in board]
        if len(board) != self.n_cells:
            raise ValueError(f"board must hold {self.n_cells} cells for the {self.name} game, got {len(board)}")
        legal = None if legal_cells is None else {int(c) for c in legal_cells}

        def symbol(cell: int) -> str:
            mark = board[cell]
            if mark != EMPTY:
                return symbols[mark]
            if legal is not None:
                return "·" if cell in legal else " "
            return "."

        return self._draw(symbol)

    def _draw(self, symbol) -> str:
        """A plain grid: column letters on top, row numbers down the side."""
        width = len(str(self.rows))
        rows = [" " * (width + 3) + "   ".join(COLUMN_LETTERS[: self.cols])]
        for r in range(self.rows):
            rows.append(f"{r + 1:<{width}}   " + " | ".join(symbol(r * self.cols + c) for c in range(self.cols)))
            if r < self.rows - 1:
                rows.append(" " * (width + 2) + "+".join(["---"] * self.cols))
        return "\n".join(rows)

    def validate(self, s: State) -> None:
        """Raise ValueError if ``s`` is not a well-formed state of this game (sizes and mark counts)."""
        if len(s.board) != self.n_cells or any(mark not in (EMPTY, X, O) for mark in s.board):
            raise ValueError(f"board must hold {self.n_cells} values in {{0, 1, 2}} for the {self.name} game")
        n_x, n_o = s.board.count(X), s.board.count(O)
        if n_x - n_o not in (0, 1):
            raise ValueError(f"board has {n_x} x and {n_o} o: x moves first, so expected #x - #o in {{0, 1}}")
        if not -1 <= s.last_move < self.n_cells:
            raise ValueError(f"last_move must be -1 or a cell 0..{self.n_cells - 1}, got {s.last_move}")


class Standard(BoardRules):
    """Noughts & Crosses on a 3x3 grid: three in a row, column or diagonal wins; a full board draws."""

    name = "standard"
    rows = cols = 3

    def result(self, board: tuple[int, ...], cell: int, mark: int) -> int:
        return mark if _has_line(board, mark) else DRAWN if EMPTY not in board else 0

    def _draw(self, symbol) -> str:
        rows = ["    a   b   c"]
        for r in range(3):
            rows.append(f"{r + 1}   " + " | ".join(symbol(r * 3 + c) for c in range(3)))
            if r < 2:
                rows.append("   ---+---+---")
        return "\n".join(rows)

    def __repr__(self) -> str:
        return "Standard()"


class Ultimate(BoardRules):
    """Ultimate Noughts & Crosses: nine 3x3 subgrids; win three subgrids in a line.

    ``free_move`` says where a player sent to a decided (won, lost or drawn) subgrid may play:
    ``"anywhere"`` (the paper's rule, default): any empty square, also inside decided subgrids;
    ``"open_subgrids"`` (the common rule, as in OpenSpiel): any empty square of an undecided subgrid.
    """

    name = "ultimate"
    rows = cols = 9

    def __init__(self, free_move: str = "anywhere") -> None:
        self.free_move = check_free_move(free_move)

    def new(self) -> State:
        return State(board=(EMPTY,) * 81, subgrids=(0,) * 9)

    def forced_subgrid(self, s: State) -> int | None:
        """The subgrid the player to move must play in, or None when free (first move, or sent to a decided one)."""
        if s.last_move < 0:
            return None
        target = TARGET_OF_CELL[s.last_move]
        return target if s.subgrids[target] == 0 else None

    def subgrid_owner(self, s: State, subgrid: int) -> Literal["x", "o", "draw"] | None:
        """Who decided subgrid ``subgrid``: "x", "o", "draw" (full, no line) or None (still open)."""
        return RESULT_NAMES[s.subgrids[subgrid]]

    def legal(self, s: State) -> list[int]:
        if s.result != 0:
            return []
        return self._legal_ignoring_result(s.board, s.subgrids, s.last_move)

    def _legal_ignoring_result(self, board: tuple[int, ...], subgrids: tuple[int, ...], last_move: int) -> list[int]:
        if last_move >= 0:
            target = TARGET_OF_CELL[last_move]
            if subgrids[target] == 0:
                return [cell for cell in SUBGRID_CELLS[target] if board[cell] == EMPTY]
        if self.free_move == "anywhere":
            return [cell for cell in range(81) if board[cell] == EMPTY]
        return sorted(cell for k in range(9) if subgrids[k] == 0 for cell in SUBGRID_CELLS[k] if board[cell] == EMPTY)

    def _after(self, s: State, cell: int, board: tuple[int, ...], mark: int) -> State:
        subgrids = s.subgrids
        k = SUBGRID_OF_CELL[cell]
        if subgrids[k] == 0:  # a decided subgrid never changes owner
            marks = [board[c] for c in SUBGRID_CELLS[k]]
            if _has_line(marks, mark):
                subgrids = subgrids[:k] + (mark,) + subgrids[k + 1:]
            elif EMPTY not in marks:
                subgrids = subgrids[:k] + (DRAWN,) + subgrids[k + 1:]
        if _has_line(subgrids, mark):
            result = mark
        elif not self._legal_ignoring_result(board, subgrids, cell):
            result = DRAWN
        else:
            result = 0
        return State(board=board, last_move=cell, subgrids=subgrids, result=result)

    def _why_illegal(self, s: State, cell: int, legal: list[int]) -> str:
        forced = self.forced_subgrid(s)
        if forced is not None:
            first, last = SUBGRID_CELLS[forced][0], SUBGRID_CELLS[forced][-1]
            return (
                f"cell {self.cell_name(cell)} ({cell}) is outside the subgrid you were sent to: "
                f"play in {self.cell_name(first)}-{self.cell_name(last)} (subgrid {forced})"
            )
        return (
            f"cell {self.cell_name(cell)} ({cell}) lies in a decided subgrid; with free_move='open_subgrids' "
            "play in a subgrid that is still open"
        )

    def validate(self, s: State) -> None:
        super().validate(s)
        if len(s.subgrids) != 9 or any(v not in (0, X, O, DRAWN) for v in s.subgrids):
            raise ValueError("subgrids must hold 9 values in {0, 1, 2, 3} for the ultimate game")

    def _draw(self, symbol) -> str:
        header = "    " + "   ".join(" ".join(COLUMN_LETTERS[b * 3 + c] for c in range(3)) for b in range(3))
        rule = "   " + "+".join(["-------"] * 3)
        rows = [header]
        for r in range(9):
            if r in (3, 6):
                rows.append(rule)
            blocks = [" ".join(symbol(r * 9 + b * 3 + c) for c in range(3)) for b in range(3)]
            rows.append(f"{r + 1:<2}  " + " | ".join(blocks))
        return "\n".join(rows)

    def __repr__(self) -> str:
        return f"Ultimate(free_move={self.free_move!r})"
