"""The ``Game`` protocol: everything the stack needs from a game, in one object (docs/games.md "Write your own game").

Why one object: the env, the opponents, the learner's augmentation, the logs, the reader and the robot all ask a game
the same few questions (its rules and outcome, its batched engine, its search positions, its example dialogues, its
sheet). A game answers them here, so a new game is one class and no part of ncbot asks which game it is.

``ncbot.envs.games.BoardGame`` answers every question from the rules alone (a small game's whole state space is
enumerated once and tabulated); a game subclasses it and gives its rules, and may replace any derived part with a
faster one (the built-ins keep their table engines and bitboards behind the same methods).
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

#: The methods a game class must have, in the order docs/games.md explains them; a class missing one is refused
#: with one line naming it (``ncbot.envs.games.load_game``).
RULE_METHODS = ("new", "legal", "play", "outcome", "mark_to_move", "cell_name", "parse_cell", "render_board")
DERIVED_METHODS = ("engine", "search_engine", "winning_cells", "rule_scores", "solver", "symmetries",
                   "example_dialogues", "threat_planes", "threat_names", "describe")
PROTOCOL_METHODS = RULE_METHODS + DERIVED_METHODS
#: The attributes a game carries (``id`` is set by the registry: how configs, checkpoints and logs name it).
PROTOCOL_ATTRIBUTES = ("name", "rows", "cols", "n_cells", "subgrids", "gravity", "sheet_grid")


@runtime_checkable
class Game(Protocol):
    """One game: rules (one state at a time, ``ncbot.envs.rules.State``) and what the stack derives from them.

    Marks: EMPTY 0, X 1, O 2 in the rules (x moves first); in engines, opponents and the env the two seats 1 (robot)
    and 2 (human), whoever opens. Cells are row-major on ``rows`` x ``cols``.
    """

    id: str  # how configs, checkpoints and logs name the game (a built-in name, a declaration, an import path)
    name: str  # a short lower-case name people read (logs, ``ncbot env describe``)
    rows: int
    cols: int
    n_cells: int
    subgrids: int  # subgrid owners the batched state tracks beside the board (Ultimate 9, one-board games 0)
    gravity: bool  # a move is a column: the mark drops to the lowest empty square (the browser, the robot's reader)
    sheet_grid: Any  # the grid the reader and the robot draw: 3, 9 (Ultimate's thick subgrid lines) or (rows, cols)

    # -- rules ---------------------------------------------------------------------------------------------------
    def new(self) -> Any:
        """The empty board, x to move."""

    def legal(self, state: Any) -> list[int]:
        """The cells the player to move may take, ascending; [] once the game is over."""

    def play(self, state: Any, cell: int) -> Any:
        """The state after the player to move takes ``cell`` (one-line ValueError for an illegal cell)."""

    def outcome(self, state: Any) -> str | None:
        """None while the game goes on, else "x", "o" (the winner) or "draw"."""

    def mark_to_move(self, state: Any) -> int:
        """1 (x) or 2 (o)."""

    def cell_name(self, cell: int) -> str:
        """How people name a cell ("b2")."""

    def parse_cell(self, text: str) -> int:
        """The inverse of ``cell_name`` (one-line ValueError otherwise)."""

    def render_board(self, board: Any, symbols: dict[int, str] | None = None, legal_cells: Any = None) -> str:
        """A board of codes as text with coordinates."""

    def describe(self) -> str:
        """One line of rules, as the browser and ``ncbot env describe`` show them."""

    # -- what the stack derives ----------------------------------------------------------------------------------
    def engine(self, readings: Any) -> Any:
        """The batched tensor engine (``ncbot.envs.engine``) under the paper's ``readings`` (``win_set``,
        ``about_to``): legal squares, moves and the one-step look-ahead rewards of whole batches."""

    def search_engine(self) -> Any:
        """Positions for tree search (``ncbot.envs.opponents.search``): from_board, moves, play, result, turn,
        rollout, position_cells."""

    def winning_cells(self, boards: Any, player: int, owners: Any = None) -> Any:
        """(B, cells) bool: where ``player`` wins the game at once (the ``winner:P`` user, the rule opponent)."""

    def rule_scores(self, boards: Any, player: int, owners: Any = None) -> Any:
        """(B, cells) int: the rule opponent's preference (win, else block, else any)."""

    def solver(self) -> Any:
        """An exact solver (``optimal_cells(boards, player)``) for ``minimax``, or None when the game is too large."""

    def symmetries(self) -> Any:
        """(G, cells) int64: the board maps that leave the rules unchanged (replay augmentation ``d4``)."""

    def example_dialogues(self, file_name: str) -> list[dict]:
        """The example dialogues of the set read from ``file_name`` (the act filter and the simulated user)."""

    def threat_planes(self, board: Any, owners: Any = None) -> Any:
        """(B, n) float32 threat features of (B, cells) boards (env option ``threat_features``)."""

    def threat_names(self) -> list[str]:
        """The names of ``threat_planes``' columns."""
