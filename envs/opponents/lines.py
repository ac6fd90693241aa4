"""Batched line arithmetic on (B, cells) boards: which cells would complete a line, and who owns each subgrid.

The rule opponent needs "where can this player complete three in a row" for a whole batch at once. Every
cell lies on 2-4 lines of its 3x3 grid; a table of each cell's partner pairs on those lines turns the
question into one gather and two reductions, with no Python loop over games. Subgrid owners are read from
the board alone: with ``free_move="anywhere"`` a subgrid can in rare cases hold lines of both players, and the
board cannot tell who was first (we then credit code 1, the robot; callers that know pass ``owners``).
"""
from __future__ import annotations

from functools import lru_cache

import torch

from ncbot.envs.core import DRAWN, LINES_3X3, SUBGRID_CELLS, SUBGRID_OF_CELL as _SUBGRID_OF_CELL

OPEN = 0
SENTINEL = -1  # value of the padding column: never a player's code, never empty

SUBGRID_INDEX = torch.tensor(SUBGRID_CELLS, dtype=torch.long)  # (9, 9) cells of each subgrid
SUBGRID_OF_CELL = torch.tensor(_SUBGRID_OF_CELL, dtype=torch.long)  # (81,) subgrid of each cell
LINE_INDEX = {
    9: torch.tensor(LINES_3X3, dtype=torch.long),
    81: torch.tensor([[SUBGRID_CELLS[k][i] for i in line] for k in range(9) for line in LINES_3X3], dtype=torch.long),
}


@lru_cache(maxsize=None)
def partner_pairs(n_cells: int) -> torch.Tensor:
    """(cells, 4, 2): for each cell, the two other cells of each line through it (padded with index ``n_cells``)."""
    pairs = [[] for _ in range(n_cells)]
    for line in LINE_INDEX[n_cells].tolist():
        for cell in line:
            pairs[cell].append([c for c in line if c != cell])
    padded = [p + [[n_cells, n_cells]] * (4 - len(p)) for p in pairs]
    return torch.tensor(padded, dtype=torch.long)


def _gather_columns(marks: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``marks[:, index]`` for a flat index; ``torch.gather`` is several times faster than advanced indexing here."""
    return torch.gather(marks, 1, index.reshape(1, -1).expand(marks.shape[0], -1))


def completing_cells(marks: torch.Tensor, owner: int, blocked: int = 0) -> torch.Tensor:
    """(B, cells) bool: cells holding ``blocked`` (empty: 0) whose line partners both hold ``owner``.

    Works on boards (cells 9 or 81, lines inside each 3x3 grid) and on (B, 9) subgrid-owner grids.
    """
    batch, cells = marks.shape
    padded = torch.cat([marks, torch.full((batch, 1), SENTINEL, dtype=marks.dtype)], dim=1)
    pairs = partner_pairs(cells)  # (cells, 4, 2)
    both = (_gather_columns(padded, pairs[..., 0]) == owner) & (_gather_columns(padded, pairs[..., 1]) == owner)
    return both.view(batch, cells, 4).any(-1) & (marks == blocked)


def subgrid_owners(boards: torch.Tensor) -> torch.Tensor:
    """(B, 9) int8 for ultimate boards: 0 open, 1 / 2 the owner's board code, 3 drawn (full, no line)."""
    batch = boards.shape[0]
    a, b, c = (_gather_columns(boards, LINE_INDEX[81][:, i]) for i in range(3))  # (B, 72) each
    owners = torch.zeros(batch, 9, dtype=torch.int8)
    for code in (2, 1):  # code 1 written last: it wins the (ambiguous) case of lines for both
        full = ((a == code) & (b == code) & (c == code)).view(batch, 9, len(LINES_3X3)).any(-1)
        owners = torch.where(full, torch.tensor(code, dtype=torch.int8), owners)
    full_grid = (_gather_columns(boards, SUBGRID_INDEX) != 0).view(batch, 9, 9).all(-1)
    return torch.where((owners == 0) & full_grid, torch.tensor(DRAWN, dtype=torch.int8), owners)


def subgrid_taking_cells(boards: torch.Tensor, code: int, owners: torch.Tensor | None = None) -> torch.Tensor:
    """(B, 81) bool: cells where player ``code`` completes a line inside a still-open subgrid."""
    open_subgrid = (subgrid_owners(boards) if owners is None else owners) == OPEN
    return completing_cells(boards, code) & open_subgrid[:, SUBGRID_OF_CELL]


def winning_cells(boards: torch.Tensor, code: int, owners: torch.Tensor | None = None,
                  takes: torch.Tensor | None = None) -> torch.Tensor:
    """(B, cells) bool: cells where player ``code`` wins the game at once (3x3 line, or Ultimate line of subgrids).

    ``takes`` may pass ``subgrid_taking_cells(boards, code, owners)`` when the caller has it already.
    """
    if boards.shape[1] == 9:
        return completing_cells(boards, code)
    owners = subgrid_owners(boards) if owners is None else owners
    takes = subgrid_taking_cells(boards, code, owners) if takes is None else takes
    # subgrids whose capture would complete a line of subgrids: two owned by `code`, the third still open
    macro_ready = completing_cells(owners, code, blocked=OPEN)  # (B, 9)
    return takes & macro_ready[:, SUBGRID_OF_CELL]
