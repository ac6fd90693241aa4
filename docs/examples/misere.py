"""Misère Noughts & Crosses as an ncbot game plugin: the 3x3 board, x first, but completing a line LOSES.

Nothing in ncbot names this game: it is loaded by its import path wherever a game is accepted, e.g.

    ncbot train pipelines/configs/default.yaml env.game=docs/examples/misere.py:Misere --out runs/misere
    ncbot robot render --game docs/examples/misere.py:Misere --marks xa1,ob2 -o misere.png

The class gives only its rules (``result``: how a move ends the game). ``BoardGame`` derives the rest from them:
the batched engine and the paper's one-step look-ahead rewards, the search positions (``mcts:N``), the exact
solver (``minimax``), the board symmetries, the example dialogues and the sheet (docs/games.md "Write your own
game").

Task success (a win or a draw, as the paper counts it) means here that the robot never completes a line of its own
before the board is full or the person completes one: a win when the person completes a line first, a draw when the
board fills with no line. Perfect play draws misère Noughts & Crosses, as it draws the usual game.
"""
from __future__ import annotations

from ncbot.envs.core import DRAWN, EMPTY, LINES_3X3, O, X
from ncbot.envs.games import BoardGame


class Misere(BoardGame):
    """Misère noughts and crosses: whoever completes three in a row, column or diagonal loses."""

    name = "misere"
    rows = cols = 3

    def result(self, board: tuple[int, ...], cell: int, mark: int) -> int:
        """The other player wins when ``mark`` completes a line; a full board without a line draws."""
        if any(cell in line and all(board[c] == mark for c in line) for line in LINES_3X3):
            return O if mark == X else X
        return DRAWN if EMPTY not in board else 0
