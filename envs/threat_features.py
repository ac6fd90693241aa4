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

import torch

from envs.core import HUMAN, LINES_3X3, ROBOT, SUBGRID_CELLS

_LINES = torch.tensor(LINES_3X3)  # (8, 3) squares of each line
_LINE_SQUARES = torch.nn.functional.one_hot(_LINES, 9).float()  # (8, 3, 9): which square each line slot is
_GRID_CELLS = torch.tensor(SUBGRID_CELLS)  # (9, 9): Ultimate cell of (subgrid, square)
_CELL_ORDER = torch.argsort(_GRID_CELLS.reshape(-1))  # (81,): (subgrid, square) order -> cell order


def completing_squares(grids: torch.Tensor, player: int) -> torch.Tensor:
    """(B, G, 9) codes of G 3x3 grids -> (B, G, 9) bool: empty squares that complete a line of ``player``."""
    lines = grids[..., _LINES]  # (B, G, 8, 3)
    two = (lines == player).sum(-1) == 2
    empty = lines == 0
    slots = (empty & two.unsqueeze(-1)).float()  # the empty slot of a line with two of the player's marks
    return torch.einsum("bgls,lsq->bgq", slots, _LINE_SQUARES) > 0


def threat_planes(board: torch.Tensor, owners: torch.Tensor | None) -> torch.Tensor:
    """(B, cells) board codes (+ (B, 9) Ultimate subgrid owners) -> (B, n) float32 planes (module doc)."""
    if board.shape[1] == 9:
        grids = board.long().unsqueeze(1)
        planes = [completing_squares(grids, p).reshape(board.shape[0], 9) for p in (ROBOT, HUMAN)]
        return torch.cat(planes, dim=1).float()
    grids = board.long()[:, _GRID_CELLS]  # (B, 9 subgrids, 9 squares)
    open_grid = (owners == 0).unsqueeze(-1)
    planes = [(completing_squares(grids, p) & open_grid).reshape(board.shape[0], 81)[:, _CELL_ORDER]
              for p in (ROBOT, HUMAN)]
    macro = owners.unsqueeze(1)  # (B, 1, 9): drawn subgrids (3) belong to nobody
    planes += [completing_squares(macro, p).reshape(board.shape[0], 9) for p in (ROBOT, HUMAN)]
    return torch.cat(planes, dim=1).float()


def threat_names(cells: int) -> list[str]:
    """Feature names of the planes, in ``threat_planes`` order."""
    width = len(str(cells - 1))
    names = [f"{side}_threat[{c:0{width}d}]" for side in ("robot", "human") for c in range(cells)]
    if cells == 81:
        names += [f"{side}_subgrid_threat[{k}]" for side in ("robot", "human") for k in range(9)]
    return names
