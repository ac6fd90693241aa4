"""Batched tensor engine for 3x3 and Ultimate Noughts & Crosses: whole-batch torch ops, no Python loop over games.

Why tables: every 3x3 grid (the whole 3x3 board, or one Ultimate subgrid) has one of 3^9 = 19,683 contents.
Precomputing, for each, "has a line", "is full", "every line blocked" and the bitmask of squares that would
complete a line lets the engine answer those questions for a whole batch with a single gather. The grid of
subgrid owners (open, robot, human, drawn) has 4^9 = 262,144 contents and gets the same treatment. This is
what makes the one-step look-ahead of all 81 Ultimate moves cheap: it is a handful of (B, 81) integer ops
instead of replaying 81 boards.

Marks: 0 empty, 1 and 2 the two players (in the env 1 = robot, 2 = human, whoever starts). Cells are numbered
row-major on the full grid (as in ``envs.rules``). Boards are ``(B, cells)`` int8.

Outcome codes: 0 game on, 1 / 2 that player won, 3 draw.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

FREE_MOVE_CHOICES = ("anywhere", "open_subgrids")
LINES_3X3 = np.array([(0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6), (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6)])
DRAWN = 3

# Look-ahead outcome codes of a move (see ``move_rewards``), in priority order.
REWARD_WIN, REWARD_DRAW, REWARD_LOSE, REWARD_ABOUT_TO_WIN, REWARD_ABOUT_TO_DRAW = 5.0, 1.0, -5.0, 5.0, 1.0


@dataclass(frozen=True)
class GridTables:
    """Per-content facts about a 3x3 grid, indexed by its base-``radix`` code sum(v_i * radix^i).

    ``win_bits[p]``: bitmask of empty squares whose taking by ``p`` completes a line of ``p``.
    ``has_line[p]``: the grid holds a line of ``p``. ``full``: no empty square. ``dead``: every line holds
    marks of both players or a value >= 3 (a drawn subgrid), so nobody can ever complete one.
    Index 0 of ``win_bits``/``has_line`` is unused so a player code indexes them directly.
    """

    win_bits: torch.Tensor  # (3, N) int64
    has_line: torch.Tensor  # (3, N) bool
    full: torch.Tensor  # (N,) bool
    dead: torch.Tensor  # (N,) bool


@lru_cache(maxsize=2)
def grid_tables(radix: int) -> GridTables:
    """Build (once) the tables for grids whose squares take values 0..radix-1 (3: marks; 4: owners)."""
    codes = np.arange(radix**9, dtype=np.int64)
    digits = (codes[:, None] // radix ** np.arange(9)) % radix  # (N, 9)
    on_lines = digits[:, LINES_3X3]  # (N, 8, 3)
    empty = on_lines == 0
    cell_bit = (1 << LINES_3X3).astype(np.int64)  # (8, 3)
    n = len(codes)
    win_bits = np.zeros((3, n), dtype=np.int64)
    has_line = np.zeros((3, n), dtype=bool)
    for player in (1, 2):
        count = (on_lines == player).sum(-1)  # (N, 8)
        completing = empty & (count == 2)[..., None]
        win_bits[player] = np.bitwise_or.reduce(np.where(completing, cell_bit, 0).reshape(n, -1), axis=1)
        has_line[player] = (count == 3).any(-1)
    blocked = ((on_lines == 1).any(-1) & (on_lines == 2).any(-1)) | (on_lines >= 3).any(-1)
    return GridTables(
        win_bits=torch.from_numpy(win_bits),
        has_line=torch.from_numpy(has_line),
        full=torch.from_numpy((digits != 0).all(-1)),
        dead=torch.from_numpy(blocked.all(-1)),
    )


def lookup(table: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``table[index]`` for a 1-D table: index_select on the flat index is several times faster on CPU."""
    return table.index_select(0, index.reshape(-1)).view(index.shape)


def lookup_rows(table: torch.Tensor, player: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``table[player, index]`` for a (3, N) table and per-row ``player``/``index`` of the same shape."""
    return lookup(table.reshape(-1), player * table.shape[1] + index)


def uniform_choice(mask: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """(B,) a uniformly random True column of each row of ``mask`` (B, n) (0 for an all-False row).

    Why not ``(rand(B, n) + mask).argmax``: torch.rand costs ~10 ns per number, so one number per row
    and the k-th True column (k = floor(u * count), via a cumulative sum) is several times faster.
    """
    counts = mask.cumsum(1, dtype=torch.int32)  # non-decreasing rows: searchsorted finds the k-th True
    total = counts[:, -1:]
    k = (torch.rand(total.shape, generator=generator) * total).to(torch.int32)
    k = torch.minimum(k, total - 1)  # u * count may round up to count in float32
    return torch.searchsorted(counts, k, right=True).squeeze(1)


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

    game: str
    cells: int
    grids: int

    def __init__(self) -> None:
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
        return torch.cat([state.board == 1, state.board == 2], dim=1).float()

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
        opponent's reply sends it); else 0. Entries of illegal cells are meaningless (the env overwrites them),
        and so are the rows outside ``active`` ((B,) bool, default all), which an engine may skip.
        """
        raise NotImplementedError

    @staticmethod
    def _as_player(player: torch.Tensor | int, like: torch.Tensor) -> torch.Tensor:
        if isinstance(player, int):
            return torch.full_like(like, player)
        return player.long()


class StandardEngine(_Engine):
    """3x3: one grid; its base-3 code answers every question."""

    game = "standard"
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
        return self._code_tables()[0], self._move_reward_rows(player)

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
        return self._move_reward_rows(player).index_select(0, state.codes[:, 0])

    @staticmethod
    @lru_cache(maxsize=2)
    def _move_reward_rows(player: int) -> torch.Tensor:
        """(3^9, 9) float32: row c holds the reward of ``player`` taking each square of the board with code c
        (one gather per step instead of ~8 ops; taken squares hold meaningless values)."""
        code = torch.arange(3**9).unsqueeze(1)  # (N, 1)
        pow3 = 3 ** torch.arange(9)
        empty = (code // pow3) % 3 == 0
        after = torch.where(empty, code + player * pow3, code)  # (N, 9): code after each move
        dead_before = lookup(grid_tables(3).dead, code).long() * 3**9
        return lookup(StandardEngine._reward_table()[player], after + dead_before).contiguous()

    @staticmethod
    @lru_cache(maxsize=1)
    def _reward_table() -> torch.Tensor:
        """(3, 2 * 3^9): reward of the board content a move of the player reached; second half: it was dead before."""
        tables = grid_tables(3)
        rows = torch.zeros(3, 2 * 3**9)
        for player in (1, 2):
            win = tables.has_line[player]
            draw = tables.full & ~win
            about_to_lose = tables.win_bits[3 - player] != 0
            about_to_win = tables.win_bits[player] != 0
            rows[player, : 3**9] = _prioritise(win, draw, about_to_lose, tables.dead, about_to_win)
            rows[player, 3**9:] = _prioritise(win, draw, about_to_lose, torch.zeros_like(win), about_to_win)
        return rows


def _prioritise(win, draw, about_to_lose, about_to_draw, about_to_win) -> torch.Tensor:
    """Combine the per-move events into the paper's reward, highest-priority event first."""
    reward = torch.where(about_to_win, REWARD_ABOUT_TO_WIN, 0.0)
    reward = torch.where(about_to_draw, REWARD_ABOUT_TO_DRAW, reward)
    reward = torch.where(about_to_lose, REWARD_LOSE, reward)
    reward = torch.where(draw, REWARD_DRAW, reward)
    return torch.where(win, REWARD_WIN, reward).float()


class UltimateEngine(_Engine):
    """Ultimate: nine subgrid codes plus the owner grid; the look-ahead works on bitmasks of subgrids."""

    game = "ultimate"
    cells = 81
    grids = 9

    def __init__(self, free_move: str = "anywhere") -> None:
        if free_move not in FREE_MOVE_CHOICES:
            raise ValueError(f"free_move must be one of {', '.join(FREE_MOVE_CHOICES)}; got {free_move!r}")
        super().__init__()
        self.free_move = free_move
        self.meta = grid_tables(4)
        cell = torch.arange(81)
        self.subgrid_of = (cell // 27) * 3 + (cell % 9) // 3  # (81,) subgrid holding the cell
        self.position_of = ((cell // 9) % 3) * 3 + (cell % 9) % 3  # (81,) position inside it = redirect target
        self.pow4 = 4 ** torch.arange(9, dtype=torch.int64)
        self.subgrid_bit = 1 << self.subgrid_of  # (81,)
        self.bit9 = 1 << torch.arange(9)
        self.cell_pow3 = self.pow3[self.position_of]  # (81,)
        self.subgrid_cells = torch.tensor([[(k // 3 * 3 + r) * 9 + k % 3 * 3 + c for r in range(3) for c in range(3)] for k in range(9)])
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
        return _prioritise(win, draw, about_to_lose, about_to_draw, about_to_win)


def make_engine(game: str, free_move: str = "anywhere") -> StandardEngine | UltimateEngine:
    """The engine of ``game`` ("standard" or "ultimate"); ValueError naming the choices otherwise."""
    if game == "standard":
        return StandardEngine()
    if game == "ultimate":
        return UltimateEngine(free_move)
    raise ValueError(f"game must be one of standard, ultimate; got {game!r}")
