"""The paper sheet's picture: a canvas the simulator draws marks on and uploads as the sheet's texture.

The canvas is kept in camera orientation (row 0 = far edge seen from the robot, column 0 = the robot's left)
so cell indices mean the same thing to the renderer, the vision reader and the game: row-major from the
top-left corner as the robot sees the sheet. The grid layout and the hand-drawn marks come from `vision`
(`ncbot.vision.sheet`, `ncbot.vision.strokes`), so what the camera sees is what the reader was built for.

Marks are redrawn from their seed at every `progress`, so a mark can grow stroke by stroke over frames
without keeping partial state; finished marks are baked into `_committed` once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncbot.vision.sheet import Grid, cell_center, cell_size, draw_sheet, grid_shape
from ncbot.vision.strokes import Stroke, draw_mark, mark_strokes

MARK_OF_PLAYER = {"x": "cross", "o": "nought"}
HUMAN_INK = (120, 40, 20)   # BGR: a blue ballpoint
ROBOT_INK = (30, 30, 30)    # BGR: the robot's black marker


@dataclass
class MarkSpec:
    """One mark on the sheet: which cell, cross/nought, who drew it (its ink), and the seed of the hand."""

    cell: int
    kind: str
    seed: int
    ink: tuple[int, int, int]
    size_fraction: float = 0.62
    #: Pen width as a fraction of the sheet's side (1.5 mm on a 0.22 m sheet is about 0.007).
    width_fraction: float = 0.007
    #: The hand's stroke model (`ncbot.vision.strokes.STYLES`).
    style: str = "pen"

    def size_px(self, grid: Grid, px: int) -> float:
        return self.size_fraction * cell_size(grid, px, px)

    def width_px(self, px: int) -> float:
        return max(1.5, self.width_fraction * px)

    def strokes(self, grid: Grid, px: int) -> list[Stroke]:
        """The pen path of this mark in canvas pixels (the same strokes `draw_mark` inks)."""
        centre = np.array(cell_center(grid, self.cell, px, px))
        # a font glyph ("hershey") has no pen path: the hand follows the pen model's strokes of the same mark
        style = "pen" if self.style == "hershey" else self.style
        strokes = mark_strokes(self.kind, self.size_px(grid, px), np.random.default_rng(self.seed), width=self.width_px(px),
                               style=style)
        return [Stroke(s.points + centre, s.widths) for s in strokes]


class SheetCanvas:
    """A BGR canvas of the game sheet with committed marks and at most one mark being drawn."""

    def __init__(self, grid: Grid, px: int = 600) -> None:
        if px < 64:
            raise ValueError(f"sheet texture must be at least 64 pixels wide; got {px}")
        self.grid = grid
        self.px = px
        self._committed = draw_sheet(grid, px, px)
        self._image: np.ndarray | None = None
        self._pending: tuple[MarkSpec, float] | None = None
        self.marks: list[MarkSpec] = []
        self.version = 0

    def _ink(self, img: np.ndarray, mark: MarkSpec, progress: float) -> None:
        draw_mark(img, mark.kind, cell_center(self.grid, mark.cell, self.px, self.px), mark.size_px(self.grid, self.px),
                  np.random.default_rng(mark.seed), progress=progress, ink=mark.ink, width=mark.width_px(self.px),
                  style=mark.style)

    def draw(self, mark: MarkSpec, progress: float) -> None:
        """Show `mark` drawn up to `progress` (0..1); at 1 it becomes part of the sheet for good.

        Partial progress is only remembered here and inked when the picture is next needed (`image`), so a
        pen moving through many waypoints between two camera frames costs one redraw, not one per waypoint.
        """
        if self._pending is not None and self._pending[0] is not mark:
            raise ValueError(f"mark in cell {self._pending[0].cell} is still being drawn; finish it first")
        progress = float(np.clip(progress, 0.0, 1.0))
        if progress >= 1.0:
            self._ink(self._committed, mark, 1.0)
            self._image = None
            self.marks.append(mark)
            self._pending = None
        else:
            self._pending = (mark, progress)
            self._image = None
        self.version += 1

    @property
    def image(self) -> np.ndarray:
        """The sheet as it looks now (BGR, camera orientation)."""
        if self._image is None:
            if self._pending is None:
                self._image = self._committed
            else:
                self._image = self._committed.copy()
                self._ink(self._image, *self._pending)
        return self._image

    @property
    def cells(self) -> int:
        """How many cells the sheet's grid has."""
        rows, cols = grid_shape(self.grid)
        return rows * cols

    def cell_pixel(self, cell: int) -> tuple[float, float]:
        return cell_center(self.grid, cell, self.px, self.px)

    def texture_rgba(self) -> np.ndarray:
        """The canvas laid out as SAPIEN's plane texture wants it (columns along +x, rows along +y), RGBA."""
        rgb = self.image[:, :, ::-1]
        turned = rgb[::-1, ::-1].transpose(1, 0, 2)
        rgba = np.empty(turned.shape[:2] + (4,), np.uint8)
        rgba[:, :, :3] = turned
        rgba[:, :, 3] = 255
        return rgba
