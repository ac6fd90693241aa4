"""Board symmetries as cell maps: row g of a (G, cells) table sends cell c (row-major) to the cell it lands on under g.

Why here: which maps leave a game unchanged is a fact about its rules, so each game answers it
(``Game.symmetries``); the learner's replay augmentation (``ncbot.modules.replay.symmetry``) only applies them.
"""
from __future__ import annotations

import torch


def square_symmetries(side: int) -> torch.Tensor:
    """(8, side*side) int64: row g maps cell c (row-major) to the cell it lands on under symmetry g (row 0 = identity)."""
    rows, cols = torch.meshgrid(torch.arange(side), torch.arange(side), indexing="ij")
    last = side - 1
    images = []
    for turned in range(4):
        r, c = rows, cols
        for _ in range(turned):  # a quarter turn clockwise: (r, c) -> (c, last - r)
            r, c = c, last - r
        images.append(r * side + c)
        images.append(r * side + (last - c))  # the same turn after a left-right mirror
    return torch.stack([image.reshape(-1) for image in images])


def board_symmetries(rows: int, cols: int, gravity: bool = False) -> torch.Tensor:
    """(G, rows*cols) int64 the maps of a rows x cols board, as ``square_symmetries``: all 8 of a square board
    without gravity, the 4 mirrors and half turn of a rectangular one, and with gravity (a mark falls down) only the
    left-right mirror."""
    if rows == cols and not gravity:
        return square_symmetries(rows)
    r, c = torch.meshgrid(torch.arange(rows), torch.arange(cols), indexing="ij")
    flips = ((False, False), (False, True)) if gravity else ((False, False), (False, True), (True, False), (True, True))
    return torch.stack([((rows - 1 - r if up else r) * cols + (cols - 1 - c if side else c)).reshape(-1)
                        for up, side in flips])
