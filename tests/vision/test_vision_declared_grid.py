"""Reading a declared game's plain rows x cols grid (4x4, 6x7) with the same reader and cell classifier."""
import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

from ncbot.vision.grid import read_board
from ncbot.vision.sheet import cell_center, cell_size, draw_grid_sheet, draw_sheet, parse_grid
from ncbot.vision.strokes import draw_mark

SYMBOL = {"cross": "x", "nought": "o"}


def _photo(rows: int, cols: int, marks: dict[int, str], seed: int) -> np.ndarray:
    """A declared sheet with hand-drawn marks, seen at a slant on a dark table."""
    page = draw_grid_sheet(rows, cols, 500, 500)
    rng = np.random.default_rng(seed)
    for cell, kind in marks.items():
        draw_mark(page, kind, cell_center((rows, cols), cell, 500, 500), 0.6 * cell_size((rows, cols), 500, 500), rng)
    frame = np.full((600, 800, 3), (70, 90, 110), np.uint8)
    to_frame = cv2.getPerspectiveTransform(np.float32([[0, 0], [500, 0], [500, 500], [0, 500]]),
                                           np.float32([[170, 60], [640, 80], [620, 560], [150, 540]]))
    cv2.warpPerspective(page, to_frame, (800, 600), frame, borderMode=cv2.BORDER_TRANSPARENT)
    return frame


def _board(rows: int, cols: int, marks: dict[int, str]) -> list[str]:
    return [SYMBOL.get(marks.get(cell, ""), "") for cell in range(rows * cols)]


@pytest.mark.parametrize("rows, cols, marks", [
    (4, 4, {0: "cross", 5: "nought", 10: "nought", 15: "cross"}),
    (6, 7, {0: "nought", 6: "cross", 20: "nought", 38: "cross", 41: "cross"}),
])
def test_reads_a_declared_grid_with_marks_and_empty(rows: int, cols: int, marks: dict[int, str]) -> None:
    assert read_board(_photo(rows, cols, marks, 1), (rows, cols)) == _board(rows, cols, marks)
    assert read_board(_photo(rows, cols, {}, 2), (rows, cols)) == [""] * (rows * cols)


def test_a_rectangular_sheet_puts_rows_down_and_columns_across() -> None:
    page = draw_grid_sheet(6, 7, 600, 600)
    x, y = (int(v) for v in cell_center((6, 7), 0, 600, 600))  # scans through cell a1's centre
    dark_rows = np.flatnonzero(page[:, x, 0] < 128)  # horizontal lines crossed by a vertical scan
    dark_cols = np.flatnonzero(page[y, :, 0] < 128)
    count = lambda idx: int((np.diff(idx) > 1).sum() + (len(idx) > 0))  # noqa: E731
    assert (count(dark_rows), count(dark_cols)) == (5, 6)
    x0, y0 = cell_center((6, 7), 0, 600, 600)
    x1, y1 = cell_center((6, 7), 41, 600, 600)
    assert x1 > x0 and y1 > y0 and (x1 - x0) / 6 == pytest.approx((y1 - y0) / 5)  # square cells
    assert (draw_grid_sheet(9, 9) != draw_sheet(9)).any()  # a declared 9x9 has no ultimate subgrid lines


def test_grid_values() -> None:
    assert [parse_grid(t) for t in ("3", "9", "4x4", "6X7", "3x3", "9x9")] == [3, 9, (4, 4), (6, 7), 3, 9]
    for bad in ("2x12", "4", "12", "x", "4x4x4", "-3x4", ""):
        with pytest.raises(ValueError, match=r"^--grid must be 3, 9 or ROWSxCOLS with 3\.\.9 each; got"):
            parse_grid(bad)
    with pytest.raises(ValueError, match=r"grid must be 3, 9 or \(rows, cols\)"):
        read_board(_photo(4, 4, {}, 0), (4, 10))


def test_cli_reads_rows_x_cols_as_json_and_refuses_a_bad_grid(tmp_path) -> None:
    marks = {3: "cross", 9: "nought"}
    image = tmp_path / "four.png"
    cv2.imwrite(str(image), _photo(4, 4, marks, 3))
    out = subprocess.run([sys.executable, "-m", "ncbot", "vision", "read", str(image), "--grid", "4x4", "--json"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["images"][0]["cells"] == _board(4, 4, marks)
    bad = subprocess.run([sys.executable, "-m", "ncbot", "vision", "read", str(image), "--grid", "2x12"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.strip().splitlines()[-1].endswith("--grid must be 3, 9 or ROWSxCOLS with 3..9 each; got 2x12")
