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

from envs.core import LINES_3X3 as _LINES, REWARD_DRAW, REWARD_LOSE, REWARD_WIN

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


def prioritise(win, draw, about_to_lose, about_to_draw, about_to_win) -> torch.Tensor:
    """Combine the per-move events into the paper's reward, highest-priority event first."""
    reward = torch.where(about_to_win, REWARD_ABOUT_TO_WIN, 0.0)
    reward = torch.where(about_to_draw, REWARD_ABOUT_TO_DRAW, reward)
    reward = torch.where(about_to_lose, REWARD_LOSE, reward)
    reward = torch.where(draw, REWARD_DRAW, reward)
    return torch.where(win, REWARD_WIN, reward).float()


