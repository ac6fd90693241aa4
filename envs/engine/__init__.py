"""Batched tensor engines of the games: whole-batch torch ops, no Python loop over games.

Why tables: every 3x3 grid (the whole 3x3 board, or one Ultimate subgrid) has one of 3^9 = 19,683 contents.
Precomputing, for each, "has a line", "is full", "every line blocked" and the bitmask of squares that would
complete a line lets the engine answer those questions for a whole batch with a single gather. The grid of
subgrid owners (open, robot, human, drawn) has 4^9 = 262,144 contents and gets the same treatment. This is
what makes the one-step look-ahead of all 81 Ultimate moves cheap: it is a handful of (B, 81) integer ops
instead of replaying 81 boards.

Marks: 0 empty, 1 and 2 the two players (in the env 1 = robot, 2 = human, whoever starts). Cells are numbered
row-major on the full grid (as in ``ncbot.envs.rules``). Boards are ``(B, cells)`` int8.

Outcome codes (``ncbot.envs.core``): 0 game on, 1 / 2 that player won, 3 draw.

Layout: ``tables`` (grid tables and gathers), ``base`` (the state and shared helpers), ``standard`` and
``ultimate`` (one engine each), ``declared`` (any declared game, ``ncbot.envs.declaration``), ``tabulated`` (a game
tabulated from its rules, ``ncbot.envs.games.table``). A game builds its own: ``make_game(game).engine(readings)``.
"""
from __future__ import annotations

from ncbot.envs.core import DRAWN  # noqa: F401  (re-exported)
from ncbot.envs.engine.base import Boards
from ncbot.envs.engine.declared import DeclaredEngine
from ncbot.envs.engine.standard import StandardEngine
from ncbot.envs.engine.tabulated import TabulatedEngine
from ncbot.envs.engine.tables import (  # noqa: F401  (re-exported)
    REWARD_ABOUT_TO_DRAW, REWARD_ABOUT_TO_WIN, GridTables, grid_tables, lookup, lookup_rows, uniform_choice,
)
from ncbot.envs.engine.ultimate import UltimateEngine

__all__ = ["Boards", "StandardEngine", "UltimateEngine", "DeclaredEngine", "TabulatedEngine", "grid_tables", "uniform_choice"]
