"""``BoardGame``: a game given by its rules alone; everything else the stack needs is derived from them.

Why derive: a researcher's new game (misère Noughts & Crosses, a game with other marks or another way to win) should
be its rules and nothing more. A small game's whole state space is enumerated once with the rules
(``ncbot.envs.games.table.GameTable``); the batched engine, the one-step look-ahead rewards, the search positions, the
exact solver, the board symmetries and the example dialogues all read that table or replay the rules. A game may
replace any of these with a faster or richer part of its own (the built-ins and the declared games do).

A subclass sets ``name``, ``rows``, ``cols`` and gives ``result`` (how a move ends the game); a game whose state holds
more than the board overrides ``new``, ``legal`` and ``_after`` instead (``ncbot.envs.rules.Ultimate``).
"""
from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING, Any

from ncbot.envs.readings import Readings
from ncbot.envs.rules import BoardRules

if TYPE_CHECKING:  # torch loads with the engine, not with the rules (configs and the CLI check games without it)
    import torch

#: The most positions (a rules state and who holds x) a game is tabulated with: 3x3 games have ~11,000, a 4x4
#: board ~20 million (too many: such a game gives its own engine, as the declared games do).
TABLE_LIMIT = 300_000


class BoardGame(BoardRules):
    """A game of marks on a rows x cols board, x first, moves alternating; see the module doc.

    Subclass it, set ``name`` (lower-case), ``rows`` and ``cols``, and define ``result(board, cell, mark)``.
    ``id`` is how configs and checkpoints name the game; the registry sets it (the import path it was loaded by).
    """

    subgrids = 0  # subgrid owners the batched state tracks (Ultimate's); a one-board game tracks none
    gravity = False  # True: a move is a column, its mark drops to the lowest empty square
    openspiel_name: str | None = None  # OpenSpiel's version of the game (``openspiel-mcts:N``), if it has one
    table_limit = TABLE_LIMIT

    @property
    def id(self) -> str:
        return self.__dict__.get("_id") or f"{type(self).__module__}:{type(self).__qualname__}"

    @id.setter
    def id(self, value: str) -> None:
        self.__dict__["_id"] = value

    @property
    def sheet_grid(self) -> Any:
        """The grid the reader and the robot draw: (rows, cols), a plain grid of square cells."""
        return (self.rows, self.cols)

    @property
    def title(self) -> str:
        """What the browser's heading calls the game."""
        return self.name.replace("_", " ")

    def describe(self) -> str:
        """One line of rules: the first line of the class docstring, else the board."""
        doc = (type(self).__doc__ or "").strip().splitlines()
        return doc[0].rstrip(".") if doc and type(self).__doc__ != BoardGame.__doc__ else \
            f"{self.name}: {self.rows} rows x {self.cols} columns"

    # -- derived from the rules: the state table -----------------------------------------------------------------
    @cached_property
    def table(self):
        """Every position of the game, enumerated once with the rules (``ncbot.envs.games.table``)."""
        from ncbot.envs.games.table import GameTable

        return GameTable(self, self.table_limit)

    def engine(self, readings: Readings = Readings()) -> Any:
        """The batched engine: row gathers from the state table (``ncbot.envs.engine.tabulated``)."""
        from ncbot.envs.engine.tabulated import TabulatedEngine

        return TabulatedEngine(self.table, readings)

    def search_engine(self) -> Any:
        """Search positions over the state table (``ncbot.envs.opponents.table_search``)."""
        from ncbot.envs.opponents.table_search import TableSearch

        return TableSearch(self.table)

    def solver(self) -> Any:
        """Exact play from the state table (negamax over every position)."""
        return self.table.solver()

    def winning_cells(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        """(B, cells) bool: the cells where ``player``, to move, wins at once (rows where it is not to move: none)."""
        return self.table.board_rows(boards, player, self.table.wins[player])

    def rule_scores(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        """(B, cells): 2 a move that wins, 1 a move after which the other side cannot win at once, 0 the rest."""
        table = self.table
        safe = table.rewards[player] > table.lose_value
        return 2 * table.board_rows(boards, player, table.wins[player]).long() + table.board_rows(boards, player, safe).long()

    def symmetries(self) -> torch.Tensor:
        """The board's turns and mirrors under which the rules are unchanged, tested on every position."""
        return self.table.symmetries()

    def example_dialogues(self, file_name: str) -> list[dict]:
        """Made from the rules with the built-in sets' skeletons and utterances (``declared_dialogue_text``)."""
        import yaml

        from ncbot.envs.data.make_example_dialogues import declared_dialogue_text

        cache = self.__dict__.setdefault("_dialogues", {})
        if file_name not in cache:
            cache[file_name] = yaml.safe_load(declared_dialogue_text(self, file_name))["dialogues"]
        return cache[file_name]

    def threat_names(self) -> list[str]:
        raise ValueError(f"game {self.name!r} defines no threat features (env option threat_features): give the game "
                         "threat_planes() and threat_names() (docs/games.md)")

    def threat_planes(self, board: torch.Tensor, owners: torch.Tensor | None = None) -> torch.Tensor:
        self.threat_names()
        raise AssertionError  # threat_names raised

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
