"""The paper game sheet: a white page with a dark-ink n x n grid, and where each cell lies on it.

One layout shared by the frame generator and the robot simulator's sheet texture, so both draw marks
where the reader looks for them. The grid is a centred square covering `GRID_FRACTION` of the page's
shorter side; 9x9 grids have thicker lines every 3 cells (the ultimate game's subgrids). The reader does
not rely on this layout: it finds the grid lines itself (`ncbot.vision.grid`).
"""
from __future__ import annotations

import cv2
import numpy as np

GRID_FRACTION = 0.82
PAPER_BGR = (246, 248, 250)
GRID_INK_BGR = (35, 35, 35)


def check_grid(grid: int) -> int:
    """Return grid if it is 3 or 9, else raise the one-line error every vision entry point shares."""
    if grid not in (3, 9):
        raise ValueError(f"grid must be 3 (noughts & crosses) or 9 (ultimate); got {grid}")
    return grid


def grid_box(grid: int, width: int, height: int) -> tuple[float, float, float]:
    """(left, top, side) of the grid square in page pixels."""
    check_grid(grid)
    side = GRID_FRACTION * min(width, height)
    return (width - side) / 2, (height - side) / 2, side


def cell_center(grid: int, cell: int, width: int, height: int) -> tuple[float, float]:
    """Pixel centre (x, y) of a row-major cell on a page of width x height pixels."""
    if not 0 <= cell < grid * grid:
        raise ValueError(f"cell must be in [0, {grid * grid}); got {cell}")
    left, top, side = grid_box(grid, width, height)
    step = side / grid
    row, col = divmod(cell, grid)
    return left + (col + 0.5) * step, top + (row + 0.5) * step


def cell_size(grid: int, width: int, height: int) -> float:
    """Side of one cell in page pixels (draw marks at ~0.5-0.8 of it)."""
    return grid_box(grid, width, height)[2] / grid


def draw_sheet(grid: int, width: int = 600, height: int = 600, border: bool = False,
               line_width: float | None = None, ink: tuple[int, int, int] = GRID_INK_BGR,
               paper: tuple[int, int, int] = PAPER_BGR) -> np.ndarray:
    """A BGR uint8 page with the grid drawn (inner lines; `border` adds the outer frame)."""
    check_grid(grid)
    if width < 40 or height < 40:
        raise ValueError(f"sheet must be at least 40x40 pixels; got {width}x{height}")
    page = np.empty((height, width, 3), np.uint8)
    page[:] = paper
    left, top, side = grid_box(grid, width, height)
    thin = line_width or max(1.0, side / 150)
    step = side / grid
    first, last = (0, grid) if border else (1, grid - 1)
    for i in range(first, last + 1):
        thick = thin * (2.2 if grid == 9 and i % 3 == 0 else 1.0)
        t = max(1, int(round(thick)))
        offset = i * step
        cv2.line(page, (int(round(left + offset)), int(round(top))), (int(round(left + offset)), int(round(top + side))),
                 ink, t, cv2.LINE_AA)
        cv2.line(page, (int(round(left)), int(round(top + offset))), (int(round(left + side)), int(round(top + offset))),
                 ink, t, cv2.LINE_AA)
    return page
