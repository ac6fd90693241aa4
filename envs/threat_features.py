"""Threat planes for the observation (env option ``threat_features``, beyond the paper, off by default).

Why: the value network that makes the Q-guided search perfect against the random user reads these threats
(``modules/search/value_net.py``), and without them the same network was much weaker; the Q-network sees marks only and has
to compute them from the mark bits. Planes, each 0/1, in this order:
- robot threats / human threats (cells each): an empty square that would complete a line of that side in its 3x3
  grid (Ultimate: only in subgrids still open);
- Ultimate only, robot / human subgrid threats (9 each): an open subgrid whose win by that side would complete a
  line of subgrids.
"""
from __future__ import annotations

import torch

from ncbot.envs.core import HUMAN, ROBOT
from ncbot.envs.opponents.bitboards import position_threat_indices  # noqa: F401  (re-exported)
from ncbot.envs.opponents.lines import OPEN, completing_cells, subgrid_owners, subgrid_taking_cells


def threat_planes(board: torch.Tensor, owners: torch.Tensor | None = None) -> torch.Tensor:
    """(B, cells) board codes (+ (B, 9) Ultimate subgrid owners) -> (B, n) float32 planes (module doc).

    Owners not given (a board whose owners are not tracked) are read from the board
    (``ncbot.envs.opponents.lines.subgrid_owners``; exact under ``open_subgrids``). The line arithmetic is the rule
    opponents' (``ncbot.envs.opponents.lines``): one gather of each cell's line partners."""
    if board.shape[1] == 9:
        planes = [completing_cells(board, p) for p in (ROBOT, HUMAN)]
    else:
        owners = subgrid_owners(board) if owners is None else owners
        planes = [subgrid_taking_cells(board, p, owners) for p in (ROBOT, HUMAN)]
        planes += [completing_cells(owners, p, blocked=OPEN) for p in (ROBOT, HUMAN)]  # drawn subgrids: nobody's
    return torch.cat(planes, dim=1).float()


def threat_names(cells: int) -> list[str]:
    """Feature names of the planes, in ``threat_planes`` order."""
    width = len(str(cells - 1))
    names = [f"{side}_threat[{c:0{width}d}]" for side in ("robot", "human") for c in range(cells)]
    if cells == 81:
        names += [f"{side}_subgrid_threat[{k}]" for side in ("robot", "human") for k in range(9)]
    return names
