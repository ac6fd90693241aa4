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

    def _open_bits(self, table_bits: torch.Tensor, owners: torch.Tensor) -> torch.Tensor:
        """(B,) bitmask over subgrids: open subgrids whose ``table_bits`` entry is non-zero."""
        return (((table_bits != 0) & (owners == 0)).long() * self.bit9).sum(1)

    @staticmethod
    @lru_cache(maxsize=1)
    def _packed_tables() -> tuple[torch.Tensor, torch.Tensor]:
        """Per player, the facts the look-ahead needs packed into one int per grid content (one gather each).

        Subgrid (3^9 contents): bit 0 has a line of the player, bit 1 full, bit 2 the opponent can complete a
        line, bit 3 the player can. Owner grid (4^9): bit 0 line of the player, bit 1 dead, bits 2-10 the
        subgrids whose winning would complete a line for the opponent, bits 11-19 the same for the player.
        """
        marks, owners = grid_tables(3), grid_tables(4)
        sub = torch.zeros(3, 3**9, dtype=torch.int64)
        meta = torch.zeros(3, 4**9, dtype=torch.int64)
        for p in (1, 2):
            q = 3 - p
            sub[p] = (
                marks.has_line[p].long() | marks.full.long() << 1
                | (marks.win_bits[q] != 0).long() << 2 | (marks.win_bits[p] != 0).long() << 3
            )
            meta[p] = owners.has_line[p].long() | owners.dead.long() << 1 | owners.win_bits[q] << 2 | owners.win_bits[p] << 11
        return sub, meta

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        """See ``_Engine.move_rewards``. Only squares that can be legal are evaluated, one subgrid (9 squares) per
        row: a game sent to an open subgrid is one row, a free game one row per subgrid it may play in. With
        ``active`` (B,) bool, only those games are evaluated (the others' entries are meaningless): the env
        passes the games where the robot has a legal move."""
        forced = self._forced(state)
        target = self.position_of.index_select(0, state.last_move.clamp(min=0))
        free = ~forced
        if active is not None:
            forced, free = forced & active, free & active
        forced_rows = forced.nonzero().squeeze(1)
        # a free game: one row per subgrid that can hold a legal square (not full; open_subgrids: undecided)
        playable = ~lookup(self.tables.full, state.codes)
        if self.free_move == "open_subgrids":
            playable = playable & (state.owners == 0)
        free_rows, free_subs = (free.unsqueeze(1) & playable).nonzero().unbind(1)
        rows = torch.cat([forced_rows, free_rows])
        subs = torch.cat([target.index_select(0, forced_rows), free_subs])
        cells = self.subgrid_cells.index_select(0, subs)  # (N, 9)
        rewards = torch.full((state.board.shape[0] * 81,), REWARD_LOSE)
        rewards.index_copy_(0, (rows.unsqueeze(1) * 81 + cells).reshape(-1), self._rewards_at(state, player, rows, subs, cells).reshape(-1))
        return rewards.view(-1, 81)

    def _rewards_at(self, state: Boards, player: int, rows: torch.Tensor, subs: torch.Tensor, cells: torch.Tensor) -> torch.Tensor:
        """(N, 9) rewards of ``player`` taking the squares ``cells`` (N, 9) of subgrid ``subs`` (N,) in games
        ``rows`` (N,), in position order (only legal squares matter). One subgrid per row keeps the subgrid's
        facts (owner, code, bit) per row, (N, 1), and the positions a constant row: few (N, 9) ops."""
        sub_table, meta_table = self._packed_tables()
        opponent = 3 - player
        # per-game facts, computed once per game and then spread over its rows
        meta_code = (state.owners * self.pow4).sum(1)  # (B,)
        opponent_now = self._open_bits(lookup(self.tables.win_bits[opponent], state.codes), state.owners)
        player_now = self._open_bits(lookup(self.tables.win_bits[player], state.codes), state.owners)
        dead_before = (lookup(meta_table[player], meta_code) & 2) != 0
        meta_code, opponent_now, player_now, dead_before = (
            t.index_select(0, rows).unsqueeze(1) for t in (meta_code, opponent_now, player_now, dead_before)
        )
        owners = state.owners.index_select(0, rows)  # (N, 9)

        sub, pos = subs.unsqueeze(1), self.positions  # (N, 1), (1, 9)
        bit = 1 << sub
        owner_s = owners.gather(1, sub)  # (N, 1)
        empty = lookup(state.board.view(-1), rows.unsqueeze(1) * 81 + cells) == 0
        code = lookup(state.codes.view(-1), rows * 9 + subs).unsqueeze(1)
        code_after = code + empty.long() * (player * self.pow3)
        facts = lookup(sub_table[player], code_after)
        open_s = owner_s == 0
        wins_sub = open_s & (facts & 1 != 0)
        draws_sub = open_s & ~wins_sub & (facts & 2 != 0)
        delta = wins_sub.long() * player + draws_sub.long() * DRAWN  # change of the subgrid's owner
        owner_after_s = owner_s + delta
        meta_facts = lookup(meta_table[player], meta_code + delta * lookup(self.pow4, sub))
        win = meta_facts & 1 != 0

        # Where the opponent is sent, and whether it can move at all.
        target_open = torch.where(pos == sub, owner_after_s, owners) == 0
        if self.free_move == "anywhere":
            free_has_moves = (state.n_marks.index_select(0, rows) < 80).unsqueeze(1)
        else:
            open_bits = ((owners == 0).long() * self.bit9).sum(1, keepdim=True)
            free_has_moves = torch.where(owner_after_s == 0, open_bits, open_bits & ~bit) != 0
        draw = ~win & ~target_open & ~free_has_moves

        # Open subgrids where each side could complete a line, after each candidate move.
        still_open = owner_after_s == 0
        opponent_threats = (opponent_now & ~bit) | ((still_open & (facts & 4 != 0)).long() * bit)
        player_threats = (player_now & ~bit) | ((still_open & (facts & 8 != 0)).long() * bit)
        opponent_threats = opponent_threats & (meta_facts >> 2 & 511)
        about_to_lose = torch.where(target_open, (opponent_threats >> pos) & 1 != 0, opponent_threats != 0)
        about_to_draw = (meta_facts & 2 != 0) & ~dead_before
        about_to_win = (player_threats & (meta_facts >> 11 & 511)) != 0
        return prioritise(win, draw, about_to_lose, about_to_draw, about_to_win)
