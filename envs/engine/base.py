"""The batched game state and what both engines share (see ``ncbot.envs.engine``)."""
from __future__ import annotations

from dataclasses import dataclass

import torch

from ncbot.envs.readings import Readings
from ncbot.envs.engine.tables import grid_tables, uniform_choice


@dataclass
class Boards:
    """The batched game state; every field has the batch as its first dimension.

    ``codes`` holds the base-3 code of each 3x3 grid (1 for the 3x3 game, 9 subgrids for Ultimate) so table
    look-ups need no re-encoding; ``owners`` the subgrid owners (Ultimate; 0 open, 1, 2, 3 drawn) which
    depend on the order of play and so cannot be derived from the board. ``move_order[c]`` is the 1-based
    number of the move that took cell c (0 if empty): the source of the temporal features.
    """

    board: torch.Tensor  # (B, cells) int8
    codes: torch.Tensor  # (B, grids) int64
    owners: torch.Tensor  # (B, 9) int64 (ultimate) / (B, 1) unused for 3x3
    last_move: torch.Tensor  # (B,) int64, -1 before the first move
    n_marks: torch.Tensor  # (B,) int64
    move_order: torch.Tensor  # (B, cells) int64
    outcome: torch.Tensor  # (B,) int64


class _Engine:
    """What both games share: state creation and the player-agnostic helpers."""

    cells: int
    grids: int

    def __init__(self, readings: Readings = Readings()) -> None:
        # the paper's readings of set A (``win_set``) and of "about to win" (``about_to``): ``ncbot.envs.readings``
        if not isinstance(readings, Readings):
            raise ValueError(f"readings must be an ncbot.envs.readings.Readings, got {readings!r}")
        self.readings = readings
        self.tables = grid_tables(3)
        self.pow3 = 3 ** torch.arange(9, dtype=torch.int64)

    def new(self, batch: int) -> Boards:
        """``batch`` empty boards."""
        return Boards(
            board=torch.zeros(batch, self.cells, dtype=torch.int8),
            codes=torch.zeros(batch, self.grids, dtype=torch.int64),
            owners=torch.zeros(batch, 9 if self.grids == 9 else 1, dtype=torch.int64),
            last_move=torch.full((batch,), -1, dtype=torch.int64),
            n_marks=torch.zeros(batch, dtype=torch.int64),
            move_order=torch.zeros(batch, self.cells, dtype=torch.int64),
            outcome=torch.zeros(batch, dtype=torch.int64),
        )

    def from_boards(self, boards: torch.Tensor, last_move: torch.Tensor | None = None) -> Boards:
        """State from raw boards: 3x3 only (Ultimate owners depend on the order of play)."""
        raise ValueError("Ultimate states depend on the order of play (subgrid owners): build them with new() and play()")

    @staticmethod
    def _place(state: Boards, cells: torch.Tensor, mark: torch.Tensor, active: torch.Tensor) -> torch.Tensor:
        """Put ``mark`` (B,) int64, 0 in the inactive rows, on ``cells`` of the ``active`` rows; returns the
        clamped cell index (B,). Adds rather than overwrites (the squares are empty: moves are legal), which
        spares reading the old values: inactive rows add 0 to their square 0."""
        cells = torch.where(active, cells, 0)
        state.board.scatter_add_(1, cells.unsqueeze(1), mark.to(torch.int8).unsqueeze(1))
        _Engine._count_move(state, cells, active)
        return cells

    @staticmethod
    def _count_move(state: Boards, cells: torch.Tensor, active: torch.Tensor) -> None:
        """Number the move on ``cells`` (B,) (valid indices) in the ``active`` rows: marks, move order, last move."""
        state.n_marks += active
        state.move_order.scatter_add_(1, cells.unsqueeze(1), (state.n_marks * active).unsqueeze(1))
        state.last_move = torch.where(active, cells, state.last_move)

    def legal(self, state: Boards) -> torch.Tensor:
        """(B, cells) bool: squares the player to move may take; all False once the game is over."""
        raise NotImplementedError

    def status(self, state: Boards) -> torch.Tensor:
        """(B,) int64 ``outcome * 2 + n_marks % 2`` (0..7): all the env's dialogue phase needs from the board."""
        return state.outcome * 2 + (state.n_marks & 1)

    def random_legal(self, state: Boards, generator: torch.Generator) -> torch.Tensor:
        """(B,) a uniformly random legal square per game (meaningless where none): ``uniform_choice(legal)``,
        same numbers from the same generator (one uniform per game)."""
        return uniform_choice(self.legal(state), generator)

    def mark_features(self, state: Boards) -> torch.Tensor:
        """(B, 2 * cells) float32: 1 where player 1 has a mark, then 1 where player 2 has one (the board features)."""
        return torch.cat(self.mark_parts(state), dim=1).float()

    def mark_parts(self, state: Boards) -> list[torch.Tensor]:
        """The mark features as parts to concatenate, 0 / 1 in any dtype: ``torch.cat`` with the observation's float
        parts makes them float32 in the same copy (the env's observation is one ``cat``, not two plus a cast)."""
        # marks are 0, 1, 2: ``& 1`` and ``>> 1`` are the two players' 0 / 1 (a scalar ``==`` on int8 is ~8x slower)
        return [state.board & 1, state.board >> 1]

    def play(self, state: Boards, cells: torch.Tensor, player: torch.Tensor | int, active: torch.Tensor | None = None) -> None:
        """In place: ``player`` (int or (B,)) takes ``cells`` (B,) in the ``active`` rows (default all).

        The caller guarantees the moves are legal (use ``legal``); the engine does not re-check, for speed.
        """
        raise NotImplementedError

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        """(B, cells) float32: the paper's one-step reward if ``player`` took each cell now (legal cells only).

        Priority: +5 the move wins; +1 it ends the game in a draw; -5 "about to lose": afterwards the opponent
        has a legal move that wins at once; +1 "about to draw": the move makes the position dead (no line can
        be completed by anyone any more) when it was not before; +5 "about to win": afterwards ``player``
        has a square that would win the game if it were ``player``'s turn (in Ultimate ignoring where the
        opponent's reply sends it) and, with ``about_to="created"``, had none before the move; else 0. Entries of illegal cells are meaningless (the env overwrites them),
        and so are the rows outside ``active`` ((B,) bool, default all), which an engine may skip.
        """
        raise NotImplementedError

    @staticmethod
    def _as_player(player: torch.Tensor | int, like: torch.Tensor) -> torch.Tensor:
        if isinstance(player, int):
            return torch.full_like(like, player)
        return player.long()


