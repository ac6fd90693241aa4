"""The 3x3 engine: one grid per game, whose base-3 code answers every question with one row gather."""
from __future__ import annotations

from functools import lru_cache

import torch

from ncbot.envs.core import DRAWN, REWARD_WIN
from ncbot.envs.engine.base import Boards, _Engine
from ncbot.envs.engine.tables import grid_tables, lookup, prioritise


class StandardEngine(_Engine):
    """3x3: one grid; its base-3 code answers every question."""

    cells = 9
    grids = 1

    def from_boards(self, boards: torch.Tensor, last_move: torch.Tensor | None = None) -> Boards:
        """State of arbitrary 3x3 ``boards`` (B, 9) (move order unknown: cells get order 1..n in index order)."""
        state = self.new(boards.shape[0])
        state.board.copy_(boards.to(torch.int8))
        state.codes[:, 0] = (boards.long() * self.pow3).sum(1)
        state.n_marks = (boards != 0).sum(1)
        state.move_order = (boards != 0).long().cumsum(1) * (boards != 0)
        if last_move is not None:
            state.last_move = last_move.clone()
        self._update_outcome(state)
        return state

    def _update_outcome(self, state: Boards) -> None:
        state.outcome = self._outcome_table().index_select(0, state.codes[:, 0])

    @staticmethod
    @lru_cache(maxsize=1)
    def _outcome_table() -> torch.Tensor:
        """(3^9,) outcome code of every 3x3 board content (positions reached by play never hold two lines)."""
        tables = grid_tables(3)
        return torch.where(tables.has_line[1], 1, torch.where(tables.has_line[2], 2, torch.where(tables.full, DRAWN, 0)))

    def legal(self, state: Boards) -> torch.Tensor:
        # one row gather instead of 4 whole-batch ops: the code holds the board, and so the outcome
        return self._code_tables()[0].index_select(0, state.codes[:, 0])

    def mark_features(self, state: Boards) -> torch.Tensor:
        return self._code_tables()[1].index_select(0, state.codes[:, 0])

    def mark_parts(self, state: Boards) -> list[torch.Tensor]:
        return [self.mark_features(state)]

    def status(self, state: Boards) -> torch.Tensor:
        return self._status_table().index_select(0, state.codes[:, 0])

    def random_legal(self, state: Boards, generator: torch.Generator) -> torch.Tensor:
        # uniform_choice's arithmetic (u * count truncated, the k-th legal square) with the count and the k-th
        # square read from tables: no cumulative sum or binary search over the batch
        code = state.codes[:, 0]
        count, nth = self._pick_tables()
        total = count.index_select(0, code)
        k = (torch.rand(total.shape, generator=generator) * total).to(torch.int64)
        return nth.index_select(0, code * 10 + k)

    def rows_by_code(self, player: int) -> tuple[torch.Tensor, torch.Tensor]:
        """(3^9, 9) bool legal squares and (3^9, 9) float32 move rewards of ``player``, row = board code: what a
        caller needs to answer "legal" and "look-ahead" for a whole batch with one row gather each."""
        return self._code_tables()[0], self._move_reward_rows(player, self.readings.about_to)

    @staticmethod
    def empty_rows_by_code() -> torch.Tensor:
        """(3^9, 9) bool, row = board code: the empty squares, whether or not the grid holds a line (the env's
        believed board under ``taken_squares="misread"`` may show a line the true board does not)."""
        return StandardEngine._empty_rows()

    @staticmethod
    @lru_cache(maxsize=1)
    def _empty_rows() -> torch.Tensor:
        return (StandardEngine._code_tables()[2] == 0).contiguous()

    def winning_rows_by_code(self, player: int) -> torch.Tensor:
        """(3^9, 9) bool, row = board code: the squares of ``player``'s set A under ``win_set``: every move worth
        +5 (``wins_and_threats``) or only the empty squares that complete a line of ``player`` now (``wins``)."""
        if self.readings.win_set == "wins":
            return self._win_rows(player)
        return self._move_reward_rows(player, self.readings.about_to) == REWARD_WIN

    @staticmethod
    @lru_cache(maxsize=2)
    def _win_rows(player: int) -> torch.Tensor:
        """(3^9, 9) bool: ``player`` taking this empty square completes a line (wins the game now)."""
        code = torch.arange(3**9).unsqueeze(1)
        pow3 = 3 ** torch.arange(9)
        empty = (code // pow3) % 3 == 0
        after = torch.where(empty, code + player * pow3, code)
        return (empty & lookup(grid_tables(3).has_line[player], after)).contiguous()

    @staticmethod
    @lru_cache(maxsize=1)
    def _status_table() -> torch.Tensor:
        """(3^9,) int64 ``outcome * 2 + marks % 2`` of every board code."""
        boards = StandardEngine._code_tables()[2]
        return StandardEngine._outcome_table() * 2 + (boards != 0).sum(1) % 2

    @staticmethod
    @lru_cache(maxsize=1)
    def _pick_tables() -> tuple[torch.Tensor, torch.Tensor]:
        """(3^9,) int32 number of legal squares; (3^9 * 10,) int64 the k-th legal square at code * 10 + k, the
        last one repeated up to k = 9 (u * count may round up to count in float32; uniform_choice clamps)."""
        legal = StandardEngine._code_tables()[0]
        running = legal.cumsum(1, dtype=torch.int32)
        count = running[:, -1].contiguous()
        k = torch.minimum(torch.arange(10, dtype=torch.int32).unsqueeze(0), (count - 1).clamp(min=0).unsqueeze(1))
        nth = torch.searchsorted(running, k.contiguous(), right=True)
        nth[count == 0] = 0  # as uniform_choice gives for a row without legal squares
        return count, nth.reshape(-1).contiguous()

    @staticmethod
    @lru_cache(maxsize=1)
    def _code_tables() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Per 3x3 code: (3^9, 9) bool legal squares (none once decided), (3^9, 18) float32 mark features and
        (3^9, 9) int8 the board itself."""
        digits = torch.arange(3**9).unsqueeze(1) // (3 ** torch.arange(9)) % 3
        open_game = StandardEngine._outcome_table() == 0
        legal = (digits == 0) & open_game.unsqueeze(1)
        marks = torch.cat([digits == 1, digits == 2], dim=1).float().contiguous()
        return legal.contiguous(), marks, digits.to(torch.int8).contiguous()

    def play(self, state: Boards, cells: torch.Tensor, player: torch.Tensor | int, active: torch.Tensor | None = None) -> None:
        if active is None:
            active = torch.ones_like(cells, dtype=torch.bool)
        mark = active * player  # (B,) int64: the player's mark in the active rows, 0 elsewhere
        cells = torch.where(active, cells, 0)
        code = state.codes.select(1, 0).add_(mark * self.pow3.index_select(0, cells))  # (`codes[:, 0] +=` adds a copy back)
        # the board and the outcome are functions of the code: one row gather each instead of a scatter
        state.board = self._code_tables()[2].index_select(0, code)
        self._count_move(state, cells, active)
        state.outcome = self._outcome_table().index_select(0, code)

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        return self._move_reward_rows(player, self.readings.about_to).index_select(0, state.codes[:, 0])

    @staticmethod
    @lru_cache(maxsize=4)
    def _move_reward_rows(player: int, about_to: str = "standing") -> torch.Tensor:
        """(3^9, 9) float32: row c holds the reward of ``player`` taking each square of the board with code c
        (one gather per step instead of ~8 ops; taken squares hold meaningless values). ``about_to="created"``:
        in the rows where ``player`` already has a winning square, "about to win" pays nothing (the table built
        without that event)."""
        code = torch.arange(3**9).unsqueeze(1)  # (N, 1)
        pow3 = 3 ** torch.arange(9)
        empty = (code // pow3) % 3 == 0
        after = torch.where(empty, code + player * pow3, code)  # (N, 9): code after each move
        dead_before = lookup(grid_tables(3).dead, code).long() * 3**9
        rows = lookup(StandardEngine._reward_table()[player], after + dead_before)
        if about_to == "created":
            had_threat = lookup(grid_tables(3).win_bits[player], code) != 0  # (N, 1)
            quiet = lookup(StandardEngine._reward_table(about_to_win=False)[player], after + dead_before)
            rows = torch.where(had_threat, quiet, rows)
        return rows.contiguous()

    @staticmethod
    @lru_cache(maxsize=2)
    def _reward_table(about_to_win: bool = True) -> torch.Tensor:
        """(3, 2 * 3^9): reward of the board content a move of the player reached; second half: it was dead before.
        ``about_to_win=False``: the same without the "about to win" event (``about_to="created"``)."""
        tables = grid_tables(3)
        rows = torch.zeros(3, 2 * 3**9)
        for player in (1, 2):
            win = tables.has_line[player]
            draw = tables.full & ~win
            about_to_lose = tables.win_bits[3 - player] != 0
            threat = (tables.win_bits[player] != 0) & about_to_win
            rows[player, : 3**9] = prioritise(win, draw, about_to_lose, tables.dead, threat)
            rows[player, 3**9:] = prioritise(win, draw, about_to_lose, torch.zeros_like(win), threat)
        return rows
