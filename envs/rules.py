"""Exact rules of Noughts & Crosses (3x3) and Ultimate Noughts & Crosses (9x9), one state at a time.

This is the small, slow, obviously-correct reference every faster engine (the batched tensor engine of the
env, the MCTS bitboards of the opponents) is checked against. States are immutable and hashable so they can
key tables (minimax) and be shared between search branches without copying.

Cells are numbered ``row * size + col`` on the full grid (size 3 or 9). Marks on the board are the ints
``EMPTY = 0``, ``X = 1``, ``O = 2``; x always moves first. In Ultimate the nine subgrids are numbered the
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
    check_free_move, check_game, subgrid_cells,
)
from ncbot.envs.declaration import Declaration, declared_game

MARK_NAMES = {X: "x", O: "o"}
RESULT_NAMES = {0: None, X: "x", O: "o", DRAWN: "draw"}


def _has_line(marks: tuple[int, ...] | list[int], mark: int) -> bool:
    """True if ``mark`` fills one of the 8 lines of the 3x3 grid ``marks``."""
    return any(marks[a] == mark and marks[b] == mark and marks[c] == mark for a, b, c in LINES_3X3)


def _single_board_after(cell: int, board: tuple[int, ...], mark: int, won: bool) -> State:
    """The state after ``mark`` took ``cell`` on a one-board game (3x3, declared): won, else drawn when the board is
    full, else still on. Only how a line is found differs between those games."""
    result = mark if won else DRAWN if EMPTY not in board else 0
    return State(board=board, last_move=cell, result=result)


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


class _Game:
    """What both games share: cell naming, turn order, move checking and rendering."""

    name: str
    size: int
    n_cells: int

    # -- basic queries -------------------------------------------------------------------------------
    def new(self) -> State:
        """The empty board, x to move."""
        raise NotImplementedError

    def legal(self, s: State) -> list[int]:
        """Cells the player to move may take, ascending; empty once the game is over."""
        raise NotImplementedError

    def _after(self, s: State, cell: int, board: tuple[int, ...], mark: int) -> State:
        raise NotImplementedError

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

    def play_many(self, cells: list[int] | tuple[int, ...], s: State | None = None) -> State:
        """Play a sequence of cells from ``s`` (default: a new game); handy for tests and replays."""
        state = self.new() if s is None else s
        for cell in cells:
            state = self.play(state, cell)
        return state

    # -- naming and drawing --------------------------------------------------------------------------
    def cell_name(self, cell: int) -> str:
        """Human name of a cell: column letter then row number from 1 at the top, e.g. 4 -> "b2"."""
        return f"{COLUMN_LETTERS[cell % self.size]}{cell // self.size + 1}"

    def parse_cell(self, text: str) -> int:
        """Inverse of ``cell_name`` (case and spaces ignored); ValueError if not a cell. Every cell a person types or
        reads is written this one way (docs/design.md, CLI conventions)."""
        cleaned = "".join(str(text).split()).lower()
        letters = COLUMN_LETTERS[: self.size]
        digits = "0123456789"  # ASCII only: "²".isdigit() is True but int("²") fails
        if len(cleaned) == 2 and cleaned[0] in letters and cleaned[1] in digits:
            row = int(cleaned[1]) - 1
            if 0 <= row < self.size:
                return row * self.size + letters.index(cleaned[0])
        raise ValueError(
            f"{text!r} is not a cell of the {self.name} board: expected a column {letters[0]}-{letters[-1]} "
            f"and a row 1-{self.size}, e.g. {self.cell_name(self.size + 1)}"
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
        raise NotImplementedError

    def validate(self, s: State) -> None:
        """Raise ValueError if ``s`` is not a well-formed state of this game (sizes and mark counts)."""
        if len(s.board) != self.n_cells or any(mark not in (EMPTY, X, O) for mark in s.board):
            raise ValueError(f"board must hold {self.n_cells} values in {{0, 1, 2}} for the {self.name} game")
        n_x, n_o = s.board.count(X), s.board.count(O)
        if n_x - n_o not in (0, 1):
            raise ValueError(f"board has {n_x} x and {n_o} o: x moves first, so expected #x - #o in {{0, 1}}")
        if not -1 <= s.last_move < self.n_cells:
            raise ValueError(f"last_move must be -1 or a cell 0..{self.n_cells - 1}, got {s.last_move}")


class Standard(_Game):
    """Noughts & Crosses on a 3x3 grid: three in a row, column or diagonal wins; a full board draws."""

    name = "standard"
    size = 3
    n_cells = 9

    def new(self) -> State:
        return State(board=(EMPTY,) * 9)

    def legal(self, s: State) -> list[int]:
        if s.result != 0:
            return []
        return [cell for cell in range(9) if s.board[cell] == EMPTY]

    def _after(self, s: State, cell: int, board: tuple[int, ...], mark: int) -> State:
        return _single_board_after(cell, board, mark, won=_has_line(board, mark))

    def _draw(self, symbol) -> str:
        rows = ["    a   b   c"]
        for r in range(3):
            rows.append(f"{r + 1}   " + " | ".join(symbol(r * 3 + c) for c in range(3)))
            if r < 2:
                rows.append("   ---+---+---")
        return "\n".join(rows)

    def __repr__(self) -> str:
        return "Standard()"


class Ultimate(_Game):
    """Ultimate Noughts & Crosses: nine 3x3 subgrids; win three subgrids in a line.

    ``free_move`` says where a player sent to a decided (won, lost or drawn) subgrid may play:
    ``"anywhere"`` (the paper's rule, default): any empty square, also inside decided subgrids;
    ``"open_subgrids"`` (the common rule, as in OpenSpiel): any empty square of an undecided subgrid.
    """

    name = "ultimate"
    size = 9
    n_cells = 81

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


NUMBER_WORDS = ("one", "two", "three", "four", "five", "six", "seven", "eight", "nine")
_SPOKEN = re.compile(r"(row|column)\s*(\w+)\s*,?\s*(?:and\s+)?(row|column)\s*(\w+)")


class Declared(_Game):
    """A declared game (``ncbot.envs.declaration``): ``k`` in a line on a rows x cols board; with ``gravity`` a mark
    drops to the lowest empty square of its column. A full board without a line draws."""

    def __init__(self, declaration: Declaration) -> None:
        self.declaration = declaration
        self.name, self.rows, self.cols = declaration.name, declaration.rows, declaration.cols
        self.size = self.cols  # cells are row * cols + col, as on the built-in boards
        self.n_cells = declaration.cells
        self.gravity = declaration.gravity
        self.lines_through = tuple(tuple(line for line in declaration.lines if cell in line) for cell in range(self.n_cells))

    def new(self) -> State:
        return State(board=(EMPTY,) * self.n_cells)

    def legal(self, s: State) -> list[int]:
        if s.result != 0:
            return []
        if not self.gravity:
            return [cell for cell in range(self.n_cells) if s.board[cell] == EMPTY]
        return sorted(cell for cell in map(lambda col: self._drop(s.board, col), range(self.cols)) if cell >= 0)

    def _drop(self, board: tuple[int, ...], col: int) -> int:
        """The lowest empty square of column ``col`` (-1 when the column is full)."""
        return next((r * self.cols + col for r in reversed(range(self.rows)) if board[r * self.cols + col] == EMPTY), -1)

    def _after(self, s: State, cell: int, board: tuple[int, ...], mark: int) -> State:
        won = any(all(board[c] == mark for c in line) for line in self.lines_through[cell])
        return _single_board_after(cell, board, mark, won=won)

    def _why_illegal(self, s: State, cell: int, legal: list[int]) -> str:
        lowest = self._drop(s.board, cell % self.cols)
        return (f"cell {self.cell_name(cell)} ({cell}) is not the lowest empty square of column "
                f"{COLUMN_LETTERS[cell % self.cols]}: a mark drops to {self.cell_name(lowest)}")

    def cell_name(self, cell: int) -> str:
        return f"{COLUMN_LETTERS[cell % self.cols]}{cell // self.cols + 1}"

    def parse_cell(self, text: str) -> int:
        """Inverse of ``cell_name`` ("b3", case and spaces ignored), or spoken: "row two column three" (either order,
        digits or number words)."""
        spoken = _SPOKEN.fullmatch(" ".join(str(text).lower().split()))
        if spoken and spoken.group(1) != spoken.group(3):
            where = {spoken.group(1): spoken.group(2), spoken.group(3): spoken.group(4)}
            row, col = _number(where["row"]), _number(where["column"], COLUMN_LETTERS)
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

    def _draw(self, symbol) -> str:
        rows = ["    " + "   ".join(COLUMN_LETTERS[: self.cols])]
        for r in range(self.rows):
            rows.append(f"{r + 1}   " + " | ".join(symbol(r * self.cols + c) for c in range(self.cols)))
            if r < self.rows - 1:
                rows.append("   " + "+".join(["---"] * self.cols))
        return "\n".join(rows)

    def __repr__(self) -> str:
        return f"Declared({self.declaration.describe()})"


def _number(word: str, letters: str = "") -> int:
    """1..9 from a digit, a number word or (a column) one of ``letters``; 0 (no cell) otherwise."""
    if word in NUMBER_WORDS:
        return NUMBER_WORDS.index(word) + 1
    if len(word) == 1 and word in letters:
        return letters.index(word) + 1
    return int(word) if len(word) == 1 and word in "123456789" else 0


Game = Standard | Ultimate | Declared


def make_game(game: str = "standard", free_move: str = "anywhere") -> Standard | Ultimate | Declared:
    """Build a game by name ("standard", "ultimate", a shipped declaration or a YAML file); ValueError otherwise."""
    game = check_game(game)
    if game == "standard":
        return Standard()
    if game == "ultimate":
        return Ultimate(free_move=free_move)
    return Declared(declared_game(game))
