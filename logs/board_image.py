"""Draw a board as a small PNG so Foxglove and rerun can show the game as it was played.

PNG rather than JPEG: the picture is flat colours and thin lines, so PNG is both smaller and exact.
"""
from __future__ import annotations

import numpy as np

ROBOT_COLOUR = (200, 60, 30)  # BGR: blue-ish crosses for the robot
HUMAN_COLOUR = (30, 30, 200)  # red noughts for the human
CELL_PIXELS = {3: 40, 9: 20}


def render_board(cells: np.ndarray | str, last_move: int = -1, cols: int = 0) -> np.ndarray:
    """An RGB uint8 image of the board: robot = X, human = O, the last move outlined in green. ``cols``: the columns
    of a declared game's board (0: a square 3x3 or 9x9 board)."""
    import cv2

    values = _cell_values(cells, cols)
    side = cols or int(round(len(values) ** 0.5))
    rows = len(values) // side
    ultimate = side == 9 and not cols
    pixels = CELL_PIXELS.get(side, 20) if not cols else 30
    width, height = side * pixels, rows * pixels
    image = np.full((height + 1, width + 1, 3), 255, np.uint8)
    for line in range(side + 1):
        cv2.line(image, (line * pixels, 0), (line * pixels, height), (0, 0, 0), 2 if ultimate and line % 3 == 0 else 1)
    for line in range(rows + 1):
        cv2.line(image, (0, line * pixels), (width, line * pixels), (0, 0, 0), 2 if ultimate and line % 3 == 0 else 1)
    margin = max(3, pixels // 5)
    for index, value in enumerate(values):
        row, col = divmod(index, side)
        x0, y0 = col * pixels, row * pixels
        if value == 1:
            cv2.line(image, (x0 + margin, y0 + margin), (x0 + pixels - margin, y0 + pixels - margin), ROBOT_COLOUR, 2)
            cv2.line(image, (x0 + pixels - margin, y0 + margin), (x0 + margin, y0 + pixels - margin), ROBOT_COLOUR, 2)
        elif value == 2:
            cv2.circle(image, (x0 + pixels // 2, y0 + pixels // 2), pixels // 2 - margin, HUMAN_COLOUR, 2)
        if index == last_move:
            cv2.rectangle(image, (x0 + 1, y0 + 1), (x0 + pixels - 1, y0 + pixels - 1), (0, 160, 0), 1)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def board_png(cells: np.ndarray | str, last_move: int = -1, cols: int = 0) -> bytes:
    """The board drawn by `render_board`, encoded as PNG bytes."""
    import cv2

    ok, encoded = cv2.imencode(".png", cv2.cvtColor(render_board(cells, last_move, cols), cv2.COLOR_RGB2BGR))
    if not ok:
        raise ValueError("could not encode the board image as PNG")
    return encoded.tobytes()


def _cell_values(cells: np.ndarray | str, cols: int = 0) -> list[int]:
    values = [int(c) for c in cells] if isinstance(cells, str) else [int(v) for v in np.asarray(cells).ravel()]
    if cols:
        if len(values) % cols or not 3 <= len(values) // cols <= 9:
            raise ValueError(f"a board of {cols} columns must have 3-9 rows of cells, got {len(values)} cells")
        return values
    side = int(round(len(values) ** 0.5))
    if side * side != len(values) or side not in (3, 9):
        raise ValueError(f"a board must have 9 or 81 cells, got {len(values)}")
    return values


def board_text(cells: np.ndarray | str, cols: int = 0) -> str:
    """The board as text lines (X robot, O human, . empty), with subgrid gaps on the 9x9 board; ``cols`` as in
    `render_board`."""
    values = _cell_values(cells, cols)
    side = cols or int(round(len(values) ** 0.5))
    marks = {0: ".", 1: "X", 2: "O"}
    lines = []
    for row in range(len(values) // side):
        line = ""
        for col in range(side):
            if side == 9 and not cols and col in (3, 6):
                line += " |"
            line += " " + marks.get(values[row * side + col], "?")
        lines.append(line)
        if side == 9 and not cols and row in (2, 5):
            lines.append(" " + "-" * (len(line) - 1))
    return "\n".join(lines)


def changed_cell(previous: str | None, cells: str) -> int:
    """The first cell that differs between two board strings (the move just made), -1 if none/unknown."""
    if previous is None or len(previous) != len(cells):
        return -1
    return next((index for index, (before, after) in enumerate(zip(previous, cells)) if before != after), -1)
