"""Batched line arithmetic on (B, cells) boards: which cells would complete a line, and who owns each subgrid.

The rule opponent needs "where can this player complete three in a row" for a whole batch at once; these
helpers answer it with a gather over a fixed table of lines and one matmul back onto the cells, so the cost
does not grow with Python loops over games. Subgrid owners are read from the board alone: with
``free_move="anywhere"`` a subgrid can in rare cases hold lines of both players, and the board cannot tell
who was first (we then credit code 1, the robot; see docs/opponents.md).
"""
from __future__ import annotations

from functools import lru_cache

import torch

from envs.rules import LINES_3X3, SUBGRID_CELLS

OPEN, DRAWN = 0, 3


@lru_cache(maxsize=None)
def _tables(n_cells: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(lines (L, 3) cell indices, subgrid of each line (L,), incidence (L*3, cells) float one-hot)."""
    if n_cells == 9:
        lines = torch.tensor(LINES_3X3, dtype=torch.long)
        line_subgrid = torch.zeros(len(LINES_3X3), dtype=torch.long)
    else:
        lines = torch.tensor([[SUBGRID_CELLS[k][i] for i in line] for k in range(9) for line in LINES_3X3], dtype=torch.long)
        line_subgrid = torch.arange(9).repeat_interleave(len(LINES_3X3))
    incidence = torch.zeros(lines.numel(), n_cells)
    incidence[torch.arange(lines.numel()), lines.reshape(-1)] = 1.0
    return lines, line_subgrid, incidence


MACRO_LINES = torch.tensor(LINES_3X3, dtype=torch.long)
MACRO_INCIDENCE = _tables(9)[2]
SUBGRID_INDEX = torch.tensor(SUBGRID_CELLS, dtype=torch.long)  # (9, 9) cells of each subgrid
SUBGRID_OF_CELL = torch.tensor([(c // 27) * 3 + (c % 9) // 3 for c in range(81)], dtype=torch.long)


def completing_cells(marks: torch.Tensor, lines: torch.Tensor, incidence: torch.Tensor, owner: int,
                     line_open: torch.Tensor | None = None, blocked: int = 0) -> torch.Tensor:
    """(B, cells) bool: empty cells that would give ``owner`` a full line.

    ``marks`` is (B, cells) of owner codes where ``blocked`` marks the empties (0 for boards). A line
    counts when two of its cells hold ``owner`` and the third equals ``blocked``; ``line_open`` (B, L)
    optionally switches lines off (lines of decided subgrids).
    """
    values = marks[:, lines]  # (B, L, 3)
    ready = ((values == owner).sum(-1) == 2) & ((values == blocked).sum(-1) == 1)
    if line_open is not None:
        ready = ready & line_open
    hits = (ready.unsqueeze(-1) & (values == blocked)).reshape(marks.shape[0], -1).float()
    return (hits @ incidence) > 0


def subgrid_owners(boards: torch.Tensor) -> torch.Tensor:
    """(B, 9) int8 for ultimate boards: 0 open, 1 / 2 the owner's board code, 3 drawn (full, no line)."""
    lines = _tables(81)[0]
    values = boards[:, lines]  # (B, 72, 3)
    owners = torch.zeros(boards.shape[0], 9, dtype=torch.int8)
    for code in (2, 1):  # code 1 written last: it wins the (ambiguous) case of lines for both
        full = (values == code).all(-1).reshape(-1, 9, len(LINES_3X3)).any(-1)
        owners = torch.where(full, torch.tensor(code, dtype=torch.int8), owners)
    full_grid = (boards[:, SUBGRID_INDEX] != 0).all(-1)
    return torch.where((owners == 0) & full_grid, torch.tensor(DRAWN, dtype=torch.int8), owners)



def winning_cells(boards: torch.Tensor, code: int, owners: torch.Tensor | None = None) -> torch.Tensor:
    """(B, cells) bool: cells where player ``code`` wins the game at once (3x3 line, or Ultimate line of subgrids)."""
    if boards.shape[1] == 9:
        lines, _, incidence = _tables(9)
        return completing_cells(boards, lines, incidence, code)
    owners = subgrid_owners(boards) if owners is None else owners
    takes = subgrid_taking_cells(boards, code, owners)
    # subgrids whose capture would complete a line of subgrids: two owned by `code`, the third still open
    macro_ready = completing_cells(owners, MACRO_LINES, MACRO_INCIDENCE, code, blocked=OPEN)  # (B, 9)
    return takes & macro_ready[:, SUBGRID_OF_CELL]


def subgrid_taking_cells(boards: torch.Tensor, code: int, owners: torch.Tensor | None = None) -> torch.Tensor:
    """(B, 81) bool: cells where player ``code`` completes a line inside a still-open subgrid."""
    lines, line_subgrid, incidence = _tables(81)
    open_subgrid = (subgrid_owners(boards) if owners is None else owners) == OPEN  # (B, 9)
    return completing_cells(boards, lines, incidence, code, line_open=open_subgrid[:, line_subgrid])
