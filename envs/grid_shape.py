"""What a game grid is, for every part that draws, reads or names its cells (the sheet, the reader, the spoken
answers): 3 (noughts & crosses), 9 (ultimate) or (rows, cols) of a declared game, each side within the range a
declaration allows (`ncbot.envs.declaration`)."""
from __future__ import annotations

from typing import Union

import numpy as np

from ncbot.envs.declaration import MAX_SIDE, MIN_SIDE

#: 3 (noughts & crosses), 9 (ultimate) or (rows, cols) of a plain declared grid.
Grid = Union[int, tuple[int, int]]


def check_grid(grid: int) -> int:
    """Return grid if it is 3 or 9, else raise the one-line error every 3x3/ultimate-only entry point shares."""
    if grid not in (3, 9):
        raise ValueError(f"grid must be 3 (noughts & crosses) or 9 (ultimate); got {grid}")
    return grid


def grid_shape(grid: Grid) -> tuple[int, int]:
    """(rows, cols) of a grid: 3, 9, or (rows, cols) with MIN_SIDE..MAX_SIDE each."""
    if isinstance(grid, (int, np.integer)) and not isinstance(grid, bool):
        return check_grid(int(grid)), int(grid)
    if (isinstance(grid, tuple) and len(grid) == 2 and all(isinstance(n, (int, np.integer)) for n in grid)
            and all(MIN_SIDE <= n <= MAX_SIDE for n in grid)):
        return int(grid[0]), int(grid[1])
    raise ValueError(f"grid must be 3, 9 or (rows, cols) with {MIN_SIDE}..{MAX_SIDE} each; got {grid!r}")
