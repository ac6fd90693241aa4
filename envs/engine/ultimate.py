"""The Ultimate engine: nine subgrid codes plus the owner grid; the look-ahead works on bitmasks of subgrids."""
from __future__ import annotations

from functools import lru_cache

import torch

from envs.core import DRAWN, REWARD_LOSE, SUBGRID_CELLS, SUBGRID_OF_CELL, TARGET_OF_CELL, check_free_move
from envs.engine.base import Boards, _Engine
from envs.engine.tables import grid_tables, lookup, lookup_rows, prioritise


class UltimateEngine(_Engine):
    """Ultimate: nine subgrid codes plus the owner grid; the look-ahead works on bitmasks of subgrids."""

    game = "ultimate"
    cells = 81
    grids = 9

    def __init__(self, free_move: str = "anywhere") -> None:
        super().__init__()
        self.free_move = check_free_move(free_move)
        self.meta = grid_tables(4)
        self.subgrid_of = torch.tensor(SUBGRID_OF_CELL)  # (81,) subgrid holding the cell
        self.position_of = torch.tensor(TARGET_OF_CELL)  # (81,) position inside it = redirect target
        self.pow4 = 4 ** torch.arange(9, dtype=torch.int64)
        self.subgrid_bit = 1 << self.subgrid_of  # (81,)
        self.bit9 = 1 << torch.arange(9)
        self.cell_pow3 = self.pow3[self.position_of]  # (81,)
        self.subgrid_cells = torch.tensor(SUBGRID_CELLS)  # (9, 9) cells of each subgrid, in position order
        # (10, 81) bool: row k < 9 the squares of subgrid k, row 9 every square (a free move)
        self.region_cells = torch.cat([self.subgrid_of.unsqueeze(0) == torch.arange(9).unsqueeze(1), torch.ones(1, 81, dtype=torch.bool)])
        self.positions = torch.arange(9).unsqueeze(0)  # (1, 9): the 9 squares of one subgrid, in position order
        self._is_position = torch.eye(9, dtype=torch.bool)  # row k: only subgrid k (a forced game's one row)
        self._grid_offsets = torch.arange(9) * 3**9  # (9,): subgrid k's block of the ``now`` table
        self._not_position = 511 - (1 << self.positions)  # (1, 9): every subgrid bit but the position's

    def legal(self, state: Boards) -> torch.Tensor:
        # one row of the (10, 81) region table per game: its forced subgrid, or row 9 (free) for the rest
        region = torch.where(self._forced(state), self.position_of.index_select(0, state.last_move.clamp(min=0)), 9)
        allowed = self.region_cells.index_select(0, region)
        if self.free_move == "open_subgrids":
            allowed = allowed & (state.owners.index_select(1, self.subgrid_of) == 0)
        return allowed & (state.board == 0) & (state.outcome == 0).unsqueeze(1)

    def _forced(self, state: Boards) -> torch.Tensor:
        """(B,) whether the player to move is sent to an open subgrid (the one at the last move's position)."""
        target = self.position_of.index_select(0, state.last_move.clamp(min=0))
        return (state.last_move >= 0) & (state.owners.gather(1, target.unsqueeze(1)).squeeze(1) == 0)

    def play(self, state: Boards, cells: torch.Tensor, player: torch.Tensor | int, active: torch.Tensor | None = None) -> None:
        if active is None:
            active = torch.ones_like(cells, dtype=torch.bool)
        player = self._as_player(player, cells)
        mark = active * player
        cells = self._place(state, cells, mark, active)
        sub = self.subgrid_of.index_select(0, cells).unsqueeze(1)
        code = state.codes.gather(1, sub).squeeze(1) + mark * self.cell_pow3.index_select(0, cells)
        state.codes.scatter_(1, sub, code.unsqueeze(1))
        owner = state.owners.gather(1, sub).squeeze(1)
        deciding = active & (owner == 0)
        won = deciding & lookup_rows(self.tables.has_line, player, code)
        drawn = deciding & ~won & lookup(self.tables.full, code)
        owner = torch.where(won, player, torch.where(drawn, DRAWN, owner))
        state.owners.scatter_(1, sub, owner.unsqueeze(1))
        meta = (state.owners * self.pow4).sum(1)
        game_won = active & lookup_rows(self.meta.has_line, player, meta)
        no_move_left = active & ~self._next_player_can_move(state)
        outcome = torch.where(game_won, player, torch.where(no_move_left, DRAWN, state.outcome))
        state.outcome = torch.where(active & (state.outcome == 0), outcome, state.outcome)

    def _next_player_can_move(self, state: Boards) -> torch.Tensor:
        """(B,) whether the player to move has any legal square (ignoring whether the game was won)."""
        target = self.position_of.index_select(0, state.last_move.clamp(min=0))
        target_open = state.owners.gather(1, target.unsqueeze(1)).squeeze(1) == 0
        if self.free_move == "anywhere":
            free = state.n_marks < 81
        else:
            free = (state.owners == 0).any(1)
        return target_open | free

    @staticmethod
    @lru_cache(maxsize=1)
    def _packed_tables() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Per player, the facts the look-ahead needs packed into ints, so one gather answers several questions.

        ``after[p]`` (3^9, 9): for each subgrid content and position, what ``p`` taking that square does to the
        subgrid (a taken square: the facts of the content as it is, as before this table): bits 0-1 its new owner if it was open (0, ``p`` or 3 drawn),
        bit 2 it stays open and the opponent can still complete a line in it, bit 11 the same for ``p`` (so
        ``after >> 2 & 0x201`` shifted by the subgrid lines up with ``now``'s two bitmasks). ``now[p]`` (9 * 3^9,): indexed by
        subgrid * 3^9 + content, ``1 << subgrid`` if the opponent can complete a line there and
        ``1 << (9 + subgrid)`` if ``p`` can (so a sum over the open subgrids gives both bitmasks). ``meta[p]``
        (4^9,): owner grid: bit 0 line of ``p``, bit 1 dead, bits 2-10 the subgrids whose winning would complete
        a line for the opponent, bits 11-19 the same for ``p``.
        """
        marks, owners = grid_tables(3), grid_tables(4)
        codes = torch.arange(3**9)
        pow3 = 3 ** torch.arange(9)
        after = torch.zeros(3, 3**9, 9, dtype=torch.int64)
        now = torch.zeros(3, 9 * 3**9, dtype=torch.int64)
        meta = torch.zeros(3, 4**9, dtype=torch.int64)
        for p in (1, 2):
            q = 3 - p
            empty = (codes.unsqueeze(1) // pow3) % 3 == 0  # (3^9, 9)
            code_after = codes.unsqueeze(1) + empty * (p * pow3)  # a taken square leaves the content as it is
            wins, full = marks.has_line[p][code_after], marks.full[code_after]
            owner = torch.where(wins, p, torch.where(full, DRAWN, 0))
            # who can still complete a line there matters only while the subgrid stays open
            still_open = (owner == 0).long()
            after[p] = owner | (marks.win_bits[q][code_after] != 0).long() * still_open << 2 | (marks.win_bits[p][code_after] != 0).long() * still_open << 11
            sub = torch.arange(9).unsqueeze(1)
            now[p] = ((marks.win_bits[q] != 0).long() << sub | (marks.win_bits[p] != 0).long() << (9 + sub)).reshape(-1)
            meta[p] = owners.has_line[p].long() | owners.dead.long() << 1 | owners.win_bits[q] << 2 | owners.win_bits[p] << 11
        return after, now, meta

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        """See ``_Engine.move_rewards``. Only squares that can be legal are evaluated, one subgrid (9 squares) per
        row: a game sent to an open subgrid is one row, a free game one row per subgrid it may play in. With
        ``active`` (B,) bool, only those games are evaluated (the others' entries are meaningless): the env
        passes the games where the robot has a legal move."""
        target = self.position_of.index_select(0, state.last_move.clamp(min=0))
        open_grid = state.owners == 0  # (B, 9)
        forced = (state.last_move >= 0) & open_grid.gather(1, target.unsqueeze(1)).squeeze(1)
        # a free game: one row per subgrid that can hold a legal square (not full; open_subgrids: undecided)
        playable = ~lookup(self.tables.full, state.codes)
        if self.free_move == "open_subgrids":
            playable = playable & open_grid
        candidates = torch.where(forced.unsqueeze(1), self._is_position.index_select(0, target), playable)
        if active is not None:
            candidates = candidates & active.unsqueeze(1)
        rows, subs = candidates.nonzero().unbind(1)  # row order does not matter: each row writes its own squares
        cells = self.subgrid_cells.index_select(0, subs)  # (N, 9)
        rewards = torch.full((state.board.shape[0] * 81,), REWARD_LOSE)
        rewards.index_copy_(0, (rows.unsqueeze(1) * 81 + cells).reshape(-1),
                            self._rewards_at(state, player, rows, subs, open_grid).reshape(-1))
        return rewards.view(-1, 81)

    def _rewards_at(self, state: Boards, player: int, rows: torch.Tensor, subs: torch.Tensor,
                    open_grid: torch.Tensor) -> torch.Tensor:
        """(N, 9) rewards of ``player`` taking the 9 squares of subgrid ``subs`` (N,) in games ``rows`` (N,), in
        position order (only legal squares matter). Sets of subgrids are 9-bit masks, so "who can still complete
        a line where" after each candidate move is a few integer ops on (N, 9) instead of (N, 9, 9) work."""
        after_table, now_table, meta_table = self._packed_tables()
        # per-game facts, computed once per game and then spread over its rows
        meta_code = (state.owners * self.pow4).sum(1)  # (B,)
        now = (lookup(now_table[player], state.codes + self._grid_offsets) * open_grid).sum(1)  # bits 0-8 opponent, 9-17 player

        open_bits = (open_grid * self.bit9).sum(1)
        dead_before = lookup(meta_table[player], meta_code) & 2
        meta_code, now, open_bits, dead_before = (t.index_select(0, rows).unsqueeze(1) for t in (meta_code, now, open_bits, dead_before))

        sub, pos = subs.unsqueeze(1), self.positions  # (N, 1), (1, 9)
        bit = 1 << sub
        code = lookup(state.codes.view(-1), rows * 9 + subs)
        after = after_table[player].index_select(0, code)  # (N, 9)
        is_open = (open_bits & bit) != 0  # the subgrid played in is undecided (anywhere: a decided one may be played in)
        delta = (after & 3) * is_open  # its new owner (0: still open, or already decided)
        meta_facts = lookup(meta_table[player], meta_code + delta * lookup(self.pow4, sub))
        win = meta_facts & 1 != 0

        # Where the opponent is sent, and whether it can move at all.
        open_after = open_bits - (delta != 0) * bit  # (N, 9) undecided subgrids after each candidate move
        target_open = (open_after >> pos) & 1  # (N, 9) 0 / 1
        if self.free_move == "anywhere":
            free_has_moves = (state.n_marks.index_select(0, rows) < 80).unsqueeze(1)
        else:
            free_has_moves = open_after != 0
        draw = ~win & (target_open == 0) & ~free_has_moves

        # Open subgrids where each side could complete a line, after each candidate move (bits 0-8 the
        # opponent, 9-17 the player), kept where winning them would complete a line of the owner grid.
        threats = (now & ~(bit * 0x201)) | (((after >> 2 & 0x201) * is_open) << sub)
        threats = threats & (meta_facts >> 2)
        # sent to an open subgrid: the opponent's threat there; else (a free move): any of its threats
        about_to_lose = (threats & (511 - target_open * self._not_position)) != 0
        about_to_draw = (meta_facts & (2 - dead_before)) != 0  # dead_before is 0 or 2
        about_to_win = threats > 511
        return prioritise(win, draw, about_to_lose, about_to_draw, about_to_win)
