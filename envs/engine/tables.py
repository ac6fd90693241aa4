"""Per-content tables of a 3x3 grid and the gathers that read them: the engines' building blocks.

Why tables: every 3x3 grid (the whole 3x3 board, or one Ultimate subgrid) has one of 3^9 = 19,683 contents.
Precomputing, for each, "has a line", "is full", "every line blocked" and the bitmask of squares that would
complete a line lets an engine answer those questions for a whole batch with a single gather. The grid of
subgrid owners (open, robot, human, drawn) has 4^9 = 262,144 contents and gets the same treatment.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

from ncbot.envs.core import LINES_3X3 as _LINES, REWARD_DRAW, REWARD_LOSE, REWARD_WIN

LINES_3X3 = np.array(_LINES)
# Look-ahead rewards of a move (see ``move_rewards``), in priority order; "about to" events pay as the event.
REWARD_ABOUT_TO_WIN, REWARD_ABOUT_TO_DRAW = REWARD_WIN, REWARD_DRAW


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


def uniform_choice_by_rows(mask: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """``uniform_choice(mask, generator)`` for a (B, n) mask with n a multiple of 9: the same numbers from the same
    generator (one uniform u per row, the k-th True column with k = u * count truncated), found over blocks of 9
    columns instead of n: each block's True columns as a 9-bit mask, their counts a table read, the block holding
    the k-th a binary search over n / 9 running counts, the column inside it a table read. Why: a (B, 81) or
    (B, 90) cumulative sum costs ~60-90 µs at batch 1024 here, the (B, n / 9) work a fraction of it."""
    count, nth = _bit_tables()
    blocks = mask.shape[1] // 9
    # a float matmul packs the bits 2x faster than an int multiply + sum, and exactly (sums of distinct powers of 2 < 2^9)
    bits = (mask.reshape(-1, 9).float() @ _BIT9_FLOAT).view(-1, blocks).long()  # (B, n / 9)
    counts = count.index_select(0, bits.view(-1)).view(bits.shape)  # int32
    running = counts.cumsum(1, dtype=torch.int32)
    total = running[:, -1:]
    k = (torch.rand(total.shape, generator=generator) * total).to(torch.int32)
    k = torch.minimum(k, total - 1)  # u * count may round up to count in float32
    block = torch.searchsorted(running, k, right=True)  # (B, 1): the block holding the k-th True column
    within = (k - running.gather(1, block) + counts.gather(1, block)).clamp(min=0)  # an all-False row: 0, column 0
    return (block * 9 + nth.index_select(0, (bits.gather(1, block) * 9 + within).view(-1)).view(-1, 1)).squeeze(1)


_BIT9_FLOAT = (1 << torch.arange(9)).float()


@lru_cache(maxsize=1)
def _bit_tables() -> tuple[torch.Tensor, torch.Tensor]:
    """(512,) int32 the number of set bits of a 9-bit mask; (512 * 9,) int64 the position of its j-th set bit at
    mask * 9 + j (j past the count: 0)."""
    bits = torch.arange(512).unsqueeze(1) >> torch.arange(9) & 1
    running = bits.cumsum(1)
    count = running[:, -1].to(torch.int32).contiguous()
    nth = torch.searchsorted(running, torch.arange(9).expand(512, 9).contiguous(), right=True)
    return count, torch.where(nth < 9, nth, 0).reshape(-1).contiguous()


def prioritise(win, draw, about_to_lose, about_to_draw, about_to_win) -> torch.Tensor:
    """Combine the per-move events into the paper's reward, highest-priority event first."""
    reward = torch.where(about_to_win, REWARD_ABOUT_TO_WIN, 0.0)
    reward = torch.where(about_to_draw, REWARD_ABOUT_TO_DRAW, reward)
    reward = torch.where(about_to_lose, REWARD_LOSE, reward)
    reward = torch.where(draw, REWARD_DRAW, reward)
    return torch.where(win, REWARD_WIN, reward).float()


