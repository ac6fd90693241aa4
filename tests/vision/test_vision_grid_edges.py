"""Harsh photos: a sparse grid's extent (3x3, a declared grid up to 5 a side) when its lines break off short or
fade to dashes, and straight scraps of marks that are no grid frame. Photos are from the TUNING split (the held-out split is
only ever evaluated); the drawn sheets are plain pictures with a known grid."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from ncbot.vision.data import HARSH_TUNING_SEED, HARSH_TUNING_STYLE_OFFSET
from ncbot.vision.data.frames import make_frame
from ncbot.vision.grid import read_board, read_page
from ncbot.vision.strokes import TUNING_STYLES

torch.set_num_threads(1)

SIDE, LEFT, STEP = 420, 60.0, 100.0  # a plain sheet: the grid spans 60..360 px both ways


def _sheet(broken: bool = False, dashed: bool = False) -> np.ndarray:
    """A white picture with a printed # (no frame): `broken` stops the right vertical line at two thirds of
    its length (a shadow's edge or a faint stretch of pen), `dashed` draws the horizontal lines in dashes
    (a vertical motion streak that fades them)."""
    img = np.full((SIDE, SIDE, 3), 250, np.uint8)
    top, bottom = int(LEFT), int(LEFT + 3 * STEP)
    for k in (1, 2):
        at = int(LEFT + k * STEP)
        stop = int(LEFT + 2 * STEP) if broken and k == 2 else bottom
        cv2.line(img, (at, top), (at, stop), (30, 30, 30), 3)
        if dashed:
            for x in range(top, bottom, 20):  # 12 px of ink, 8 px gaps
                cv2.line(img, (x, at), (min(x + 12, bottom), at), (30, 30, 30), 3)
        else:
            cv2.line(img, (top, at), (bottom, at), (30, 30, 30), 3)
    return img


def _grid_error(img: np.ndarray) -> float:
    """Largest distance (in cells) of the grid corners the reader found from the drawn ones."""
    found = read_page(img, 3).grid_corners
    truth = np.array([[LEFT, LEFT], [LEFT + 3 * STEP, LEFT], [LEFT + 3 * STEP, LEFT + 3 * STEP], [LEFT, LEFT + 3 * STEP]])
    return float(np.abs(found - truth).max() / STEP)


def test_a_grid_line_broken_off_short_does_not_shrink_the_grid() -> None:
    assert _grid_error(_sheet()) < 0.1
    # the median end of the two vertical lines (360 and 260 px) put the bottom edge a sixth of the grid high
    assert _grid_error(_sheet(broken=True)) < 0.1


@pytest.mark.parametrize("cells", [4, 5])
def test_lines_broken_off_short_do_not_shrink_a_declared_sparse_grid(cells: int) -> None:
    """A declared grid up to 5 a side takes its edges from the even spacing of its inner lines, as 3x3 does: with
    all but one vertical line stopping at half the grid's height, the median of their ends put the bottom edge
    half a grid high."""
    step = 300.0 / cells
    img = np.full((SIDE, SIDE, 3), 250, np.uint8)
    top, bottom = int(LEFT), int(LEFT + 300)
    for k in range(1, cells):
        at = int(LEFT + k * step)
        stop = bottom if k == 1 else int(LEFT + 150)
        cv2.line(img, (at, top), (at, stop), (30, 30, 30), 3)
        cv2.line(img, (top, at), (bottom, at), (30, 30, 30), 3)
    found = read_page(img, (cells, cells)).grid_corners
    truth = np.array([[LEFT, LEFT], [LEFT + 300, LEFT], [LEFT + 300, LEFT + 300], [LEFT, LEFT + 300]])
    assert float(np.abs(found - truth).max() / step) < 0.15


def test_grid_lines_faded_to_dashes_are_still_found() -> None:
    # a reader without the dash repair finds no horizontal line in dashes (no run reaches a fifth of the page)
    assert _grid_error(_sheet(dashed=True)) < 0.1


@pytest.mark.parametrize("styles,offset,photos", [
    # pen tuning photos a reader without the line-end repairs misreads: broken line ends (0, 4, 19, 172, 219, 292, 360),
    # a scrap of a mark taken for a frame (338), a motion-faded line lost (54), no grid found (223, 273)
    (("pen",), 0, (0, 4, 19, 54, 172, 219, 223, 273, 292, 338, 360)),
    # marker (tuning-style) photos with broken line ends
    (TUNING_STYLES, HARSH_TUNING_STYLE_OFFSET, (0, 21, 26, 37, 39)),
])
def test_harsh_3x3_tuning_photos_with_broken_or_faded_lines_are_read(styles, offset, photos) -> None:
    wrong = {}
    for i in photos:
        frame = make_frame(3, HARSH_TUNING_SEED + 300_000 + offset + i, styles=styles, conditions="harsh")
        try:
            cells = read_board(frame.image, 3)
        except ValueError:
            cells = [None] * 9
        if cells != frame.board:
            wrong[i] = sum(a != b for a, b in zip(cells, frame.board))
    assert not wrong, wrong
