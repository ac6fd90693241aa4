"""The paper game sheet: a white page with a dark-ink grid, and where each cell lies on it.

One layout shared by the frame generator and the robot simulator's sheet texture, so both draw marks
where the reader looks for them. A grid is 3 (noughts & crosses), 9 (ultimate) or (rows, cols) of a
declared game (`ncbot.envs.declaration`), with square cells: its longer side covers `GRID_FRACTION` of the
page's shorter side, centred; 9x9 ultimate grids have thicker lines every 3 cells (the subgrids). The
reader does not rely on this layout: it finds the grid lines itself (`ncbot.vision.grid`).
"""
from __future__ import annotations

from typing import Union

import cv2
import numpy as np

GRID_FRACTION = 0.82
PAPER_BGR = (246, 248, 250)
GRID_INK_BGR = (35, 35, 35)


#: 3 (noughts & crosses), 9 (ultimate) or (rows, cols) of a plain declared grid.
Grid = Union[int, tuple[int, int]]
SIDE_RANGE = (3, 9)  # rows and cols of a declared grid, as `ncbot.envs.declaration` allows
SPARSE_SIDE = 5      # a declared grid with at most this many cells a side is photographed and read like 3x3, else like 9x9


def check_grid(grid: int) -> int:
    """Return grid if it is 3 or 9, else raise the one-line error every 3x3/ultimate-only entry point shares."""
    if grid not in (3, 9):
        raise ValueError(f"grid must be 3 (noughts & crosses) or 9 (ultimate); got {grid}")
    return grid


def grid_shape(grid: Grid) -> tuple[int, int]:
    """(rows, cols) of a grid the reader and the sheet take: 3, 9, or (rows, cols) with 3..9 each."""
    if isinstance(grid, (int, np.integer)) and not isinstance(grid, bool):
        return check_grid(int(grid)), int(grid)
    low, high = SIDE_RANGE
    if (isinstance(grid, tuple) and len(grid) == 2 and all(isinstance(n, (int, np.integer)) for n in grid)
            and all(low <= n <= high for n in grid)):
        return int(grid[0]), int(grid[1])
    raise ValueError(f"grid must be 3, 9 or (rows, cols) with {low}..{high} each; got {grid!r}")


def game_grid(game) -> Grid:
    """The grid of a game's sheet (any object with ``sheet_grid``, ``name``, ``rows`` and ``cols``: an
    ``ncbot.envs.games`` game); a one-line ValueError when the reader and the sheet cannot draw it."""
    try:
        grid_shape(game.sheet_grid)
    except ValueError:
        low, high = SIDE_RANGE
        raise ValueError(f"game {game.name!r} has a {game.rows}x{game.cols} board: the sheet, the reader and the robot "
                         f"draw 3x3, Ultimate's 9x9 or plain grids of {low}..{high} rows and columns") from None
    return game.sheet_grid


def built_in_like(grid: Grid) -> int:
    """The built-in size (3 or 9) a grid is treated like where sizes differ: how close the camera comes (the
    photo generator) and the reader's page warp, rho and hand size; a declared grid goes by its longer side."""
    if isinstance(grid, (int, np.integer)) and not isinstance(grid, bool):
        return check_grid(int(grid))
    return 3 if max(grid_shape(grid)) <= SPARSE_SIDE else 9


def parse_grid(text: str) -> Grid:
    """`--grid` as typed: "3" or "9" (the built-in games), or "ROWSxCOLS" (a plain grid; 3x3 and 9x9 read as 3
    and 9, the same cells)."""
    low, high = SIDE_RANGE
    error = ValueError(f"--grid must be 3, 9 or ROWSxCOLS with {low}..{high} each; got {text}")
    parts = text.strip().lower().split("x")
    if not all(p.isdigit() for p in parts) or len(parts) not in (1, 2):
        raise error
    if len(parts) == 1:
        if int(parts[0]) not in (3, 9):
            raise error
        return int(parts[0])
    rows, cols = int(parts[0]), int(parts[1])
    if not (low <= rows <= high and low <= cols <= high):
        raise error
    return rows if rows == cols and rows in (3, 9) else (rows, cols)


def grid_label(grid: Grid) -> str:
    """"4x4", "6x7": how messages name a grid."""
    rows, cols = grid_shape(grid)
    return f"{rows}x{cols}"


def grid_box(grid: Grid, width: int, height: int) -> tuple[float, float, float]:
    """(left, top, side) in page pixels of the square holding the grid (a rectangular grid's longer side)."""
    grid_shape(grid)
    side = GRID_FRACTION * min(width, height)
    return (width - side) / 2, (height - side) / 2, side


def grid_layout(grid: Grid, width: int, height: int) -> tuple[float, float, float, float, float]:
    """(left, top, grid width, grid height, cell step) in page pixels: a rectangle centred in `grid_box`; the
    one place that says where the lines and cells lie (the sheet, the photo generator's truth)."""
    rows, cols = grid_shape(grid)
    left, top, side = grid_box(grid, width, height)
    step = side / max(rows, cols)
    across = side if cols >= rows else step * cols
    down = side if rows >= cols else step * rows
    return left + (side - across) / 2, top + (side - down) / 2, across, down, step


def cell_center(grid: Grid, cell: int, width: int, height: int) -> tuple[float, float]:
    """Pixel centre (x, y) of a row-major cell on a page of width x height pixels."""
    rows, cols = grid_shape(grid)
    if not 0 <= cell < rows * cols:
        raise ValueError(f"cell must be in [0, {rows * cols}); got {cell}")
    left, top, _, _, step = grid_layout(grid, width, height)
    row, col = divmod(cell, cols)
    return left + (col + 0.5) * step, top + (row + 0.5) * step


def cell_size(grid: Grid, width: int, height: int) -> float:
    """Side of one cell in page pixels (draw marks at ~0.5-0.8 of it)."""
    return grid_layout(grid, width, height)[4]


def draw_sheet(grid: Grid, width: int = 600, height: int = 600, border: bool = False,
               line_width: float | None = None, ink: tuple[int, int, int] = GRID_INK_BGR,
               paper: tuple[int, int, int] = PAPER_BGR) -> np.ndarray:
    """A BGR uint8 page with the grid drawn (inner lines; `border` adds the outer frame)."""
    rows, cols = grid_shape(grid)
    if width < 40 or height < 40:
        raise ValueError(f"sheet must be at least 40x40 pixels; got {width}x{height}")
    page = np.empty((height, width, 3), np.uint8)
    page[:] = paper
    left, top, across, down, step = grid_layout(grid, width, height)
    thin = line_width or max(1.0, max(across, down) / 150)
    ultimate = isinstance(grid, (int, np.integer)) and grid == 9

    def width_of(i: int) -> int:
        return max(1, int(round(thin * (2.2 if ultimate and i % 3 == 0 else 1.0))))

    # vertical and horizontal line i in turn (anti-aliased crossings blend in drawing order)
    for i in range(0 if border else 1, max(rows, cols) + (1 if border else 0)):
        if i < cols or (border and i == cols):
            x = int(round(left + i * step))
            cv2.line(page, (x, int(round(top))), (x, int(round(top + down))), ink, width_of(i), cv2.LINE_AA)
        if i < rows or (border and i == rows):
            y = int(round(top + i * step))
            cv2.line(page, (int(round(left)), y), (int(round(left + across)), y), ink, width_of(i), cv2.LINE_AA)
    return page


def draw_grid_sheet(rows: int, cols: int, width: int = 600, height: int = 600, border: bool = False) -> np.ndarray:
    """A declared game's sheet: a plain rows x cols grid (no ultimate subgrid lines, even at 9x9)."""
    return draw_sheet(grid_shape((rows, cols)), width, height, border)
