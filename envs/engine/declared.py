"""The batched engine of a declared game (``ncbot.envs.declaration``): any rows x cols board, k in a line, gravity.

Why line counts instead of content tables: a 3x3 grid has 3^9 contents, a 6x7 board 3^42, so nothing can be
tabulated per content. Instead each game's marks are counted on every winning line with one matmul against the
(lines, cells) incidence matrix; every question of the look-ahead ("which squares win now", "does the opponent
keep a winning square after this move", "does this move leave no line open") is then a few more matmuls and
comparisons over (B, cells), with no Python loop over games or candidate moves. With gravity the squares a player
may take are the lowest empty one of each column; a move at c makes the square above c playable.

``tests/envs/test_declared.py`` checks every answer against a brute-force replay of each move with the exact rules.
"""
from __future__ import annotations

import torch

from ncbot.envs.core import DRAWN, REWARD_LOSE, REWARD_WIN
from ncbot.envs.declaration import Declaration
from ncbot.envs.engine.base import Boards, _Engine
from ncbot.envs.engine.tables import prioritise, uniform_choice
from ncbot.envs.readings import Readings


class DeclaredEngine(_Engine):
    """The engine of one declared game; the same interface as the Ultimate engine (the env's generic path)."""

    grids = 1

    def __init__(self, declaration: Declaration, readings: Readings = Readings()) -> None:
        super().__init__(readings)
        self.declaration = declaration
        self.cells, self.k = declaration.cells, declaration.k
        self.rows, self.cols, self.gravity = declaration.rows, declaration.cols, declaration.gravity
        lines = torch.tensor(declaration.lines, dtype=torch.int64)  # (L, k)
        incidence = torch.zeros(len(lines), self.cells)
        incidence.scatter_(1, lines, 1.0)
        self.incidence = incidence  # (L, cells) float: line l holds cell c
        self.incidence_t = incidence.t().contiguous()  # (cells, L)
        self.vertical = (lines[:, 1] - lines[:, 0] == self.cols).unsqueeze(0)  # (1, L)
        cell = torch.arange(self.cells)
        self.bottom = (cell >= self.cells - self.cols).unsqueeze(0)  # (1, cells): nothing below
        self.below = torch.where(self.bottom.squeeze(0), cell, cell + self.cols)  # a bottom square points at itself
        self.above = (cell - self.cols).clamp(min=0)
        self.has_above = (cell >= self.cols).unsqueeze(0)

    # -- state ---------------------------------------------------------------------------------------
    def from_boards(self, boards: torch.Tensor, last_move: torch.Tensor | None = None) -> Boards:
        """State of arbitrary ``boards`` (B, cells) (move order unknown: cells get order 1..n in index order)."""
        state = self.new(boards.shape[0])
        state.board.copy_(boards.to(torch.int8))
        taken = boards != 0
        state.n_marks = taken.sum(1)
        state.move_order = taken.long().cumsum(1) * taken
        if last_move is not None:
            state.last_move = last_move.clone()
        won1, won2 = (self._counts(state.board, p).eq(self.k).any(1) for p in (1, 2))
        full = state.n_marks == self.cells
        state.outcome = torch.where(won1, 1, torch.where(won2, 2, torch.where(full, DRAWN, 0)))
        return state

    def _counts(self, board: torch.Tensor, player: int | torch.Tensor) -> torch.Tensor:
        """(B, L) float: ``player``'s marks on every line (``player`` an int or (B, 1))."""
        return (board == player).float() @ self.incidence_t

    def playable(self, board: torch.Tensor) -> torch.Tensor:
        """(B, cells) bool: the empty squares a player may take on ``board``, whether or not the game is over."""
        empty = board == 0
        if not self.gravity:
            return empty
        return empty & (self.bottom | (board.gather(1, self.below.expand(board.shape[0], -1)) != 0))

    def legal(self, state: Boards, active: torch.Tensor | None = None) -> torch.Tensor:
        """See ``_Engine.legal``; with ``active`` (B,) bool the rows outside it are all False."""
        playing = state.outcome == 0 if active is None else (state.outcome == 0) & active
        return self.playable(state.board) & playing.unsqueeze(1)

    def random_legal(self, state: Boards, generator: torch.Generator) -> torch.Tensor:
        return uniform_choice(self.legal(state), generator)

    def play(self, state: Boards, cells: torch.Tensor, player: torch.Tensor | int, active: torch.Tensor | None = None) -> None:
        if active is None:
            active = torch.ones_like(cells, dtype=torch.bool)
        player = self._as_player(player, cells)
        cells = self._place(state, cells, active * player, active)
        won = self._counts(state.board, player.unsqueeze(1)).eq(self.k).any(1)
        outcome = torch.where(won, player, torch.where(state.n_marks == self.cells, DRAWN, 0))
        state.outcome = torch.where(active & (state.outcome == 0), outcome, state.outcome)

    # -- look-ahead ----------------------------------------------------------------------------------
    def winning_squares(self, board: torch.Tensor, player: int) -> torch.Tensor:
        """(B, cells) bool: the playable squares where ``player`` completes a line now (the rule opponent's question)."""
        return self._line_cells(board, player)[0] & self.playable(board)

    def _line_cells(self, board: torch.Tensor, player: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(B, cells) bool empty squares completing a line of ``player``; (B, L) its marks and the other's per line."""
        mine, theirs = self._counts(board, player), self._counts(board, 3 - player)
        open_lines = (mine == self.k - 1) & (theirs == 0)
        return ((open_lines.float() @ self.incidence) > 0) & (board == 0), mine, theirs

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        """See ``_Engine.move_rewards`` (here every square that is not legal holds -5)."""
        rewards = torch.full((state.board.shape[0], self.cells), REWARD_LOSE)
        self.write_move_rewards(rewards, state, player, active)
        return rewards

    def write_move_rewards(self, out: torch.Tensor, state: Boards, player: int, active: torch.Tensor | None = None,
                           wins: torch.Tensor | None = None) -> None:
        """Write ``player``'s reward of every legal square into the first ``cells`` columns of ``out`` (B, W), in
        place, in the rows of ``active`` (default all); other entries are left as they are. ``wins`` (B, W) bool, if
        given, gets True where the written reward is +5 (``win_set="wins"``: where the move wins now)."""
        rows = torch.arange(state.board.shape[0]) if active is None else active.nonzero().squeeze(1)
        if rows.numel() == 0:
            return
        board = state.board.index_select(0, rows)
        legal = self.playable(board) & (state.outcome.index_select(0, rows) == 0).unsqueeze(1)
        reward, win = self._rewards(board, state.n_marks.index_select(0, rows), player)
        cells = out[:, : self.cells]
        cells.index_copy_(0, rows, torch.where(legal, reward, cells.index_select(0, rows)))
        if wins is not None:
            is_win = win if self.readings.win_set == "wins" else reward == REWARD_WIN
            target = wins[:, : self.cells]
            target.index_copy_(0, rows, torch.where(legal, is_win, target.index_select(0, rows)))

    def _after_move(self, winning: torch.Tensor, playable: torch.Tensor) -> torch.Tensor:
        """(B, cells) bool: for each candidate move c, the player still has a winning square after c (one of
        ``winning`` other than c; with gravity one that is playable after c, where c makes the square above it so)."""
        if not self.gravity:
            return winning.sum(1, keepdim=True) - winning.long() > 0
        now = winning & playable
        above = winning.gather(1, self.above.expand(winning.shape[0], -1)) & self.has_above
        return now.sum(1, keepdim=True) - now.long() + above.long() > 0

    def _rewards(self, board: torch.Tensor, n_marks: torch.Tensor, p: int) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, cells) float32 the reward of ``p`` taking each square (meaningful on legal squares) and (N, cells) bool
        whether the move wins now."""
        playable = self.playable(board)
        win, mine, theirs = self._line_cells(board, p)
        their_wins = self._line_cells(board, 3 - p)[0]
        draw = (n_marks + 1 == self.cells).unsqueeze(1) & ~win
        about_to_lose = self._after_move(their_wins, playable)
        # dead: every line holds both players' marks. A move of p closes the lines through it holding the other's only.
        unblocked = ((mine == 0) | (theirs == 0)).sum(1, keepdim=True).float()
        closed = ((mine == 0) & (theirs > 0)).float() @ self.incidence
        about_to_draw = (unblocked - closed == 0) & (unblocked > 0)
        # about to win: a winning square left over, or a line through the move with k - 2 marks of p and none of the
        # other (its second empty square then wins; with gravity it must be playable after the move)
        twos = (mine == self.k - 2) & (theirs == 0)
        if self.gravity:
            playable_on_line = (board == 0).logical_and(playable).float() @ self.incidence_t
            twos = twos & ((playable_on_line == 2) | self.vertical)
        about_to_win = self._after_move(win, playable) | ((twos.float() @ self.incidence) > 0)
        if self.readings.about_to == "created":
            had = (win & playable).any(1, keepdim=True)
            about_to_win = about_to_win & ~had
        return prioritise(win, draw, about_to_lose, about_to_draw, about_to_win), win
