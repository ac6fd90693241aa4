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
from ncbot.envs.opponents.bitboards import CELL_OF, COMPLETING, FULL, SQUARES_OF_MASK
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


def position_threat_indices(pos: tuple, cells: int) -> list[int]:
    """Indices into the ``threat_planes`` of one bitboard position (``ncbot.envs.opponents.bitboards``) that are 1, seen
    from the side to move (its threats first, as the robot's).

    Why: the Q-guided search builds one position's features per expansion; the batched torch version costs ~0.3 ms
    there, these table lookups a few microseconds, and the bitboard knows the exact subgrid owners. Tested equal to
    ``threat_planes`` on random games of both games."""
    if cells == 9:
        bits0, bits1, turn, _ = pos
        sides = (bits0, bits1) if turn == 0 else (bits1, bits0)
        free = FULL ^ (bits0 | bits1)
        return [plane * 9 + c for plane, bits in enumerate(sides) for c in SQUARES_OF_MASK[COMPLETING[bits] & free]]
    subs0, subs1, decided, macro0, macro1, _, turn = pos[:7]
    sides, macros = ((subs0, subs1), (macro0, macro1)) if turn == 0 else ((subs1, subs0), (macro1, macro0))
    indices = []
    for plane, subs in enumerate(sides):
        for k in SQUARES_OF_MASK[FULL ^ decided]:  # open subgrids only
            threats = COMPLETING[subs[k]] & (FULL ^ (subs0[k] | subs1[k]))
            indices += [plane * 81 + CELL_OF[k][p] for p in SQUARES_OF_MASK[threats]]
    for plane, macro in enumerate(macros):
        indices += [162 + plane * 9 + k for k in SQUARES_OF_MASK[COMPLETING[macro] & (FULL ^ decided)]]
    return indices


def threat_names(cells: int) -> list[str]:
    """Feature names of the planes, in ``threat_planes`` order."""
    width = len(str(cells - 1))
    names = [f"{side}_threat[{c:0{width}d}]" for side in ("robot", "human") for c in range(cells)]
    if cells == 81:
        names += [f"{side}_subgrid_threat[{k}]" for side in ("robot", "human") for k in range(9)]
    return names
