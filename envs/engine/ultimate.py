"""The Ultimate engine: nine subgrid codes plus the owner grid; the look-ahead works on bitmasks of subgrids."""
from __future__ import annotations

from functools import lru_cache

import torch

from ncbot.envs.core import DRAWN, REWARD_LOSE, REWARD_WIN, SUBGRID_CELLS, SUBGRID_OF_CELL, TARGET_OF_CELL, check_free_move
from ncbot.envs.engine.base import Boards, _Engine
from ncbot.envs.engine.tables import grid_tables, lookup, lookup_rows, prioritise, uniform_choice_by_rows
from ncbot.envs.readings import Readings


class UltimateEngine(_Engine):
    """Ultimate: nine subgrid codes plus the owner grid; the look-ahead works on bitmasks of subgrids."""

    cells = 81
    grids = 9

    def __init__(self, free_move: str = "anywhere", readings: Readings = Readings()) -> None:
        super().__init__(readings)
        self.free_move = check_free_move(free_move)
        self.meta = grid_tables(4)
        self.subgrid_of = torch.tensor(SUBGRID_OF_CELL)  # (81,) subgrid holding the cell
        self.position_of = torch.tensor(TARGET_OF_CELL)  # (81,) position inside it = redirect target
        self.pow4 = 4 ** torch.arange(9, dtype=torch.int64)
        self.subgrid_bit = 1 << self.subgrid_of  # (81,)
        self.bit9 = 1 << torch.arange(9)
        self.cell_pow3 = self.pow3[self.position_of]  # (81,)
        self.subgrid_cells = torch.tensor(SUBGRID_CELLS)  # (9, 9) cells of each subgrid, in position order
        self.positions = torch.arange(9).unsqueeze(0)  # (1, 9): the 9 squares of one subgrid, in position order
        self._is_position = torch.eye(9, dtype=torch.bool)  # row k: only subgrid k (a forced game's one row)
        self._grid_offsets = torch.arange(9) * 3**9  # (9,): subgrid k's block of the ``now`` table
        self._not_position = 511 - (1 << self.positions)  # (1, 9): every subgrid bit but the position's
        # int32 copies for the look-ahead's (N, 9) arithmetic
        self._positions32, self._not_position32 = self.positions.to(torch.int32), self._not_position.to(torch.int32)
        self._pow4_32 = self.pow4.to(torch.int32)
        self._event_bits = tuple(torch.tensor(v, dtype=torch.int32) for v in (4, 8, 16))
        # (11, 81) bool: row k < 9 the squares of subgrid k, row 9 every square (a free move), row 10 none
        self.region_cells = torch.cat([self.subgrid_of.unsqueeze(0) == torch.arange(9).unsqueeze(1),
                                       torch.ones(1, 81, dtype=torch.bool), torch.zeros(1, 81, dtype=torch.bool)])

    def legal(self, state: Boards, active: torch.Tensor | None = None) -> torch.Tensor:
        """See ``_Engine.legal``; with ``active`` (B,) bool, the rows outside it are all False (the env passes the
        games whose act filter allows a move). One row of the (11, 81) region table per game: its forced subgrid,
        every square (a free move) or none (a finished game, a row outside ``active``), AND the empty squares."""
        target = self.position_of.index_select(0, state.last_move.clamp(min=0))
        forced = (state.last_move >= 0) & (state.owners.gather(1, target.unsqueeze(1)).squeeze(1) == 0)
        playing = state.outcome == 0 if active is None else (state.outcome == 0) & active
        allowed = self.region_cells.index_select(0, torch.where(playing, torch.where(forced, target, 9), 10))
        if self.free_move == "open_subgrids":
            allowed = allowed & (state.owners.index_select(1, self.subgrid_of) == 0)
        return allowed & state.board.logical_not()  # (``board == 0`` with a scalar is ~20x slower on int8 here)

    def random_legal(self, state: Boards, generator: torch.Generator) -> torch.Tensor:
        """See ``_Engine.random_legal``; ``uniform_choice_by_rows``: the same numbers without a (B, 81) cumulative sum."""
        return uniform_choice_by_rows(self.legal(state), generator)

    def play(self, state: Boards, cells: torch.Tensor, player: torch.Tensor | int, active: torch.Tensor | None = None) -> None:
        if active is None:
            active = torch.ones_like(cells, dtype=torch.bool)
        one_player = isinstance(player, int)  # the env's case: one table row per player instead of per-row gathers
        player = player if one_player else self._as_player(player, cells)
        mark = active * player
        cells = self._place(state, cells, mark, active)
        sub = self.subgrid_of.index_select(0, cells).unsqueeze(1)
        code = state.codes.gather(1, sub).squeeze(1) + mark * self.cell_pow3.index_select(0, cells)
        state.codes.scatter_(1, sub, code.unsqueeze(1))
        owner = state.owners.gather(1, sub).squeeze(1)
        deciding = active & (owner == 0)
        if one_player:  # the subgrid's owner after the move in one read (player, drawn or still open)
            owner = torch.where(deciding, lookup(self._owner_after()[player], code), owner)
            game_won = active & lookup(self.meta.has_line[player], (state.owners.scatter_(1, sub, owner.unsqueeze(1)) * self.pow4).sum(1))
        else:
            won = deciding & lookup_rows(self.tables.has_line, player, code)
            drawn = deciding & ~won & lookup(self.tables.full, code)
            owner = torch.where(won, player, torch.where(drawn, DRAWN, owner))
            state.owners.scatter_(1, sub, owner.unsqueeze(1))
            game_won = active & lookup_rows(self.meta.has_line, player, (state.owners * self.pow4).sum(1))
        no_move_left = active & ~self._next_player_can_move(state)
        outcome = torch.where(game_won, player, torch.where(no_move_left, DRAWN, state.outcome))
        state.outcome = torch.where(active & (state.outcome == 0), outcome, state.outcome)

    @staticmethod
    @lru_cache(maxsize=1)
    def _owner_after() -> torch.Tensor:
        """(3, 3^9) int64: the owner of a subgrid with this content once ``p`` moved there: ``p`` with a line of
        ``p``, else 3 (drawn) when full, else 0 (open)."""
        tables = grid_tables(3)
        rows = torch.zeros(3, 3**9, dtype=torch.int64)
        for p in (1, 2):
            rows[p] = torch.where(tables.has_line[p], p, torch.where(tables.full, DRAWN, 0))
        return rows

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

        ``after[p]`` (2 * 3^9, 9): at open * 3^9 + content, for each position, what ``p`` taking that square does to
        an open subgrid (open = 1; a decided one, open = 0, only bit 5) (a taken square: the facts of the content as it is, as before this table): bits 0-1 its new owner if it was open (0, ``p`` or 3 drawn),
        bit 2 it stays open and the opponent can still complete a line in it, bit 11 the same for ``p`` (so
        ``after >> 2 & 0x201`` shifted by the subgrid lines up with ``now``'s two bitmasks), bit 5 the square is
        taken (the events' bit 5, see ``_event_tables``). ``now[p]`` (9 * 3^9,): indexed by
        subgrid * 3^9 + content, ``1 << subgrid`` if the opponent can complete a line there and
        ``1 << (9 + subgrid)`` if ``p`` can (so a sum over the open subgrids gives both bitmasks). ``meta[p]``
        (4^9,): owner grid: bit 0 line of ``p``, bit 1 dead, bits 2-10 the subgrids whose winning would complete
        a line for the opponent, bits 11-19 the same for ``p``.
        """
        marks, owners = grid_tables(3), grid_tables(4)
        codes = torch.arange(3**9)
        pow3 = 3 ** torch.arange(9)
        after = torch.zeros(3, 2 * 3**9, 9, dtype=torch.int64)
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
            facts = owner | (marks.win_bits[q][code_after] != 0).long() * still_open << 2 | (marks.win_bits[p][code_after] != 0).long() * still_open << 11
            taken = (~empty).long() << 5
            after[p, : 3**9] = taken  # the subgrid is decided: no new owner, no threat
            after[p, 3**9:] = facts | taken
            sub = torch.arange(9).unsqueeze(1)
            now[p] = ((marks.win_bits[q] != 0).long() << sub | (marks.win_bits[p] != 0).long() << (9 + sub)).reshape(-1)
            meta[p] = owners.has_line[p].long() | owners.dead.long() << 1 | owners.win_bits[q] << 2 | owners.win_bits[p] << 11
        return after.to(torch.int32), now.to(torch.int32), meta.to(torch.int32)  # every fact fits 22 bits

    def move_rewards(self, state: Boards, player: int, active: torch.Tensor | None = None) -> torch.Tensor:
        """See ``_Engine.move_rewards`` (here every taken square, and every square outside ``active``, holds -5)."""
        rewards = torch.full((state.board.shape[0], 81), REWARD_LOSE)
        self.write_move_rewards(rewards, state, player, active)
        return rewards

    def write_move_rewards(self, out: torch.Tensor, state: Boards, player: int, active: torch.Tensor | None = None,
                           wins: torch.Tensor | None = None) -> None:
        """Write ``player``'s move rewards into the first 81 columns of ``out`` (B, W) float32 (contiguous), in
        place: every square of each subgrid the player may play in (a taken square: -5); the other entries are
        left as they are, so the env writes them straight into its (B, actions) look-ahead row (its other
        entries already -5 or the dialogue acts' 0). ``wins`` (B, W) bool (contiguous), if given, gets True
        where the written reward is +5 (the env's ``winning_actions``, without a float compare of the whole row),
        or with ``win_set="wins"`` only where the move wins the game now.
        Only squares that can be legal are evaluated, one subgrid (9 squares) per row: a game sent to an open
        subgrid is one row, a free game one row per subgrid it may play in. With ``active`` (B,) bool, only those
        games are evaluated: the env passes the games where the robot has a legal move."""
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
        squares = ((rows * out.shape[1]).unsqueeze(1) + self.subgrid_cells.index_select(0, subs)).view(-1)  # flat indices
        events = self._events_at(state, player, rows, subs, open_grid).view(-1)
        rewards, is_plus5, is_game_win = self._event_tables()
        is_win = is_game_win if self.readings.win_set == "wins" else is_plus5
        # scatter_ rather than index_copy_: the same writes (the indices are distinct), ~4x faster here
        out.view(-1).scatter_(0, squares, rewards.index_select(0, events))
        if wins is not None:
            wins.view(-1).scatter_(0, squares, is_win.index_select(0, events))

    @staticmethod
    @lru_cache(maxsize=1)
    def _event_tables() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(64,) float32 the reward of a move from its events' bits (bit 0 win, 1 about to draw, 2 draw, 3 about
        to lose, 4 about to win, 5 the square is taken), highest priority first as ``prioritise`` does; (64,)
        bool whether that reward is +5; (64,) bool whether the move wins the game now (``win_set="wins"``)."""
        bits = torch.arange(64).unsqueeze(1) >> torch.arange(6) & 1 == 1
        taken = bits[:, 5]
        reward = prioritise(bits[:, 0], bits[:, 2], bits[:, 3], bits[:, 1], bits[:, 4])
        reward = torch.where(taken, REWARD_LOSE, reward).float().contiguous()
        return reward, (reward == REWARD_WIN).contiguous(), (bits[:, 0] & ~taken).contiguous()

    def _events_at(self, state: Boards, player: int, rows: torch.Tensor, subs: torch.Tensor,
                   open_grid: torch.Tensor) -> torch.Tensor:
        """(N, 9) int32 events (bits, see ``_event_tables``) of ``player`` taking the 9 squares of subgrid
        ``subs`` (N,) in games ``rows`` (N,), in position order. Sets of subgrids are 9-bit masks, so "who can
        still complete a line where" after each candidate move is a few integer ops on (N, 9) instead of
        (N, 9, 9) work; the reward is then one read of a 64-entry table (five float ``where``s cost ~5x more)."""
        after_table, now_table, meta_table = self._packed_tables()
        i32 = torch.int32  # every fact fits 22 bits: int32 halves the memory traffic of the (N, 9) ops
        # per-game facts, computed once per game and then spread over its rows
        meta_code = (state.owners * self.pow4).sum(1)  # (B,)
        now = (lookup(now_table[player], state.codes + self._grid_offsets) * open_grid).sum(1)  # bits 0-8 opponent, 9-17 player

        open_bits = (open_grid * self.bit9).sum(1)
        meta_now = lookup(meta_table[player], meta_code)
        dead_before = meta_now & 2
        # about_to="created": the player already has a winning square (an open subgrid where it can complete a
        # line whose winning completes a line of subgrids: the "about to win" test below, before the move)
        had_threat = ((now & (meta_now >> 2)) > 511) if self.readings.about_to == "created" else None
        meta_code, now, open_bits, dead_before = (t.index_select(0, rows).unsqueeze(1).to(i32) for t in (meta_code, now, open_bits, dead_before))

        sub, pos = subs.unsqueeze(1).to(i32), self._positions32  # (N, 1), (1, 9)
        bit = 1 << sub
        # the subgrid played in is undecided (anywhere: a decided one may be played in): the table's second half
        # is the same facts with the new owner and both threat bits cleared (a decided subgrid stays decided)
        is_open = (open_bits & bit) != 0
        code = lookup(state.codes.view(-1), rows * 9 + subs) + is_open.squeeze(1) * 3**9
        after = after_table[player].index_select(0, code)  # (N, 9)
        delta = after & 3  # its new owner (0: still open, or already decided)
        meta_facts = lookup(meta_table[player], meta_code + delta * lookup(self._pow4_32, sub))
        events = meta_facts & (3 - dead_before)  # bit 0 the move wins, bit 1 it makes the game dead (was not)

        # Where the opponent is sent, and whether it can move at all: a draw if sent to a decided subgrid
        # without a free square anywhere (open_subgrids: no undecided subgrid, so the target is decided too)
        open_after = open_bits - (delta != 0) * bit  # (N, 9) undecided subgrids after each candidate move
        target_open = (open_after >> pos) & 1  # (N, 9) 0 / 1
        four, eight, sixteen = self._event_bits  # 0-d int32 tensors: bool * them stays int32
        if self.free_move == "anywhere":
            no_free = state.n_marks.index_select(0, rows) >= 80  # (N,): the move fills the board
            if bool(no_free.any()):  # rare (the last squares): skip three (N, 9) ops otherwise
                events = events | (1 - target_open) * (no_free.unsqueeze(1) * four)
        else:
            events = events | (open_after == 0) * four

        # Open subgrids where each side could complete a line, after each candidate move (bits 0-8 the
        # opponent, 9-17 the player), kept where winning them would complete a line of the owner grid.
        threats = (now & ~(bit * 0x201)) | ((after >> 2 & 0x201) << sub)
        threats = threats & (meta_facts >> 2)
        # sent to an open subgrid: the opponent's threat there; else (a free move): any of its threats
        events = events | ((threats & (511 - target_open * self._not_position32)) != 0) * eight  # about to lose
        about_to_win = threats > 511
        if had_threat is not None:  # created: paid only on the move that makes the first threat
            about_to_win = about_to_win & ~had_threat.index_select(0, rows).unsqueeze(1)
        events = events | about_to_win * sixteen  # about to win
        return events | (after & 32)  # the square is taken (bit 5 of ``after``)
