"""What a robot game settled, for the reader that learns from play: the robot's looks at the sheet and the moves
both sides agreed on.

The robot looks at the sheet after every settled move (its own mark checked; the person's move confirmed, or
answered where the camera missed it). At the end of the game both sides agree on the moves made: an honest person
on the moves as they were drawn; a person who claims moves they did not make (`HumanConfig.wrong_claims`) on some of
their moves placed elsewhere. The looks labelled by the agreed moves (`ncbot.vision.online.settled_examples`) are
what the reader learns from; the looks' times and the agreed moves also go into the game's `/episode` summary, so a
log can be learned from again later (`ncbot learn LOGS`).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ncbot.vision.labels import CROSS, NOUGHT
from ncbot.vision.online.examples import View

ROBOT, HUMAN = 1, 2  # the players as the true boards spell them (`RobotGameRunner._true_digits`)


def moves_from_boards(boards: Sequence[str]) -> list[tuple[int, int]]:
    """(cell, player) of every move, in order, from the true board after each move (digit strings, 1 robot, 2 human)."""
    moves, before = [], None
    for board in boards:
        changed = [i for i, value in enumerate(board) if value != "0" and (before is None or before[i] == "0")]
        if len(changed) != 1:
            raise ValueError(f"the boards of a game must differ by one new mark each; {before} -> {board}")
        moves.append((changed[0], int(board[changed[0]])))
        before = board
    return moves


def claim_moves(moves: Sequence[tuple[int, int]], cells: int, share: float,
                rng: np.random.Generator) -> list[tuple[int, int]]:
    """The moves a person who claims moves they did not make agrees on: each of their moves, with probability
    `share`, placed in a cell that stayed empty all game (so the claimed game is still a game); the robot's own
    moves are never disputed."""
    if share <= 0:
        return list(moves)
    free = [cell for cell in range(cells) if cell not in {c for c, _ in moves}]
    claimed = []
    for cell, player in moves:
        if player == HUMAN and free and rng.random() < share:
            cell = free.pop(int(rng.integers(len(free))))
        claimed.append((cell, player))
    return claimed


def labelled_moves(moves: Sequence[tuple[int, int]], robot_first: bool) -> list[tuple[int, int]]:
    """(cell, label index) of each move: the first player draws crosses."""
    robot_label, human_label = (CROSS, NOUGHT) if robot_first else (NOUGHT, CROSS)
    return [(cell, robot_label if player == ROBOT else human_label) for cell, player in moves]


class GameViews:
    """The robot's looks at the sheet in one game, as the reader cuts their cells. Each frame goes through the same
    JPEG encoding as the MCAP log's camera stream, so learning from the log later sees the very same cells."""

    def __init__(self, grid, jpeg_quality: int) -> None:
        self.grid = grid
        self.jpeg_quality = jpeg_quality
        self.views: list[View] = []
        self.unread = 0  # looks in which the reader found no sheet or grid

    def add(self, frame_bgr: np.ndarray, moves: int) -> None:
        import cv2

        from ncbot.vision.grid import extract_cells

        ok, jpeg = cv2.imencode(".jpg", frame_bgr, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        image = cv2.imdecode(jpeg, cv2.IMREAD_COLOR) if ok else frame_bgr
        try:
            self.views.append(View(extract_cells(image, self.grid).cell_images, int(moves)))
        except ValueError:
            self.unread += 1

    def take(self) -> list[View]:
        """This game's views; the next game starts with none."""
        views, self.views = self.views, []
        return views
