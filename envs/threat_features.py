"""Threat planes for the observation (env option ``threat_features``, beyond the paper, off by default).

Why: the value network that makes the Q-guided search perfect against the random user reads these threats
(``modules/value_net.py``), and without them the same network was much weaker; the Q-network sees marks only and has
to compute them from the mark bits. Planes, each 0/1, in this order:
- robot threats / human threats (cells each): an empty square that would complete a line of that side in its 3x3
  grid (Ultimate: only in subgrids still open);
- Ultimate only, robot / human subgrid threats (9 each): an open subgrid whose win by that side would complete a
  line of subgrids.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

from envs.core import DRAWN, HUMAN, ROBOT
from envs.opponents.lines import (LINE_INDEX, OPEN, SENTINEL, SUBGRID_INDEX, SUBGRID_OF_CELL, completing_cells,
                                  partner_pairs, subgrid_owners, subgrid_taking_cells)


def threat_planes(board: torch.Tensor, owners: torch.Tensor | None) -> torch.Tensor:
    """(B, cells) board codes (+ (B, 9) Ultimate subgrid owners) -> (B, n) float32 planes (module doc).

    The line arithmetic is the rule opponents' (``envs.opponents.lines``): one gather of each cell's line partners."""
    if board.shape[1] == 9:
        planes = [completing_cells(board, p) for p in (ROBOT, HUMAN)]
    else:
        planes = [subgrid_taking_cells(board, p, owners) for p in (ROBOT, HUMAN)]
        planes += [completing_cells(owners, p, blocked=OPEN) for p in (ROBOT, HUMAN)]  # drawn subgrids: nobody's
    return torch.cat(planes, dim=1).float()


def threat_planes_of_board(board: torch.Tensor, owners: torch.Tensor | None = None) -> torch.Tensor:
    """``threat_planes`` of (B, cells) boards whose subgrid owners are not tracked: read from the board
    (``envs.opponents.lines.subgrid_owners``; exact under ``open_subgrids``)."""
    if board.shape[1] == 81 and owners is None:
        owners = subgrid_owners(board)
    return threat_planes(board, owners)


@lru_cache(maxsize=None)
def _tables(cells: int) -> tuple[np.ndarray, ...]:
    """numpy copies of the line tables: cell partner pairs, the 9-cell owner grid's pairs, Ultimate's lines."""
    return (partner_pairs(cells).numpy(), partner_pairs(9).numpy(), LINE_INDEX[81].numpy(), SUBGRID_INDEX.numpy(),
            SUBGRID_OF_CELL.numpy())


def _completing(marks: np.ndarray, pairs: np.ndarray, owner: int, blocked: int = 0) -> np.ndarray:
    padded = np.append(marks, SENTINEL)
    return ((padded[pairs[..., 0]] == owner) & (padded[pairs[..., 1]] == owner)).any(-1) & (marks == blocked)


def position_threat_planes(board: np.ndarray) -> np.ndarray:
    """(n,) float32 ``threat_planes_of_board`` of one (cells,) int8 board, in numpy.

    Why: the Q-guided search builds one position's features per expansion; the batched torch version costs ~0.3 ms
    there, this ~0.03 ms. Tested equal to the torch version on random games."""
    pairs, grid_pairs, lines, subgrid_cells, subgrid_of_cell = _tables(board.shape[0])
    if board.shape[0] == 9:
        planes = [_completing(board, pairs, p) for p in (ROBOT, HUMAN)]
    else:
        marks = board[lines]  # (72, 3): the 8 lines of each subgrid
        owners = np.zeros(9, dtype=np.int8)
        for code in (HUMAN, ROBOT):  # ROBOT written last, as in subgrid_owners
            owners[(marks == code).all(1).reshape(9, -1).any(1)] = code
        owners[(owners == OPEN) & (board[subgrid_cells] != 0).all(1)] = DRAWN
        open_cell = (owners == OPEN)[subgrid_of_cell]
        planes = [_completing(board, pairs, p) & open_cell for p in (ROBOT, HUMAN)]
        planes += [_completing(owners, grid_pairs, p, blocked=OPEN) for p in (ROBOT, HUMAN)]
    return np.concatenate(planes).astype(np.float32)


def threat_names(cells: int) -> list[str]:
    """Feature names of the planes, in ``threat_planes`` order."""
    width = len(str(cells - 1))
    names = [f"{side}_threat[{c:0{width}d}]" for side in ("robot", "human") for c in range(cells)]
    if cells == 81:
        names += [f"{side}_subgrid_threat[{k}]" for side in ("robot", "human") for k in range(9)]
    return names
